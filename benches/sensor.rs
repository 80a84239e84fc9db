//! The fused sensor kernel at full size (2448 x 2048): `cargo bench --bench sensor`.
//! `frame_fast/*` = sensor-frame Stokes rows → 12-bit codes (optics, polarizer, PRNU, dark
//! current, shot and read noise, DSNU, full well, ADC); `frame_exact` = the exact path.
//! `noise/normal_5M` = 5 M normal deviates from the counter-based generator, one thread.

use criterion::{criterion_group, criterion_main, Criterion};
use psns::camera::Intrinsics;
use psns::sensor::{self, fast, Sensor, SensorConfig};
use std::hint::black_box;

fn bench(cr: &mut Criterion) {
    let intr = Intrinsics::default();
    let (w, h) = (intr.width, intr.height);
    let cfg = SensorConfig::default();
    let sensor = Sensor::new(&cfg, &intr, 1).unwrap();
    // a polarized flat field at about half the full well
    let st = sensor::flat_field(w, h, 0.05, 0.3, 30.0).unwrap();
    let mut g = cr.benchmark_group("frame_fast");
    g.sample_size(10);
    let mut codes = Vec::new();
    g.bench_function("flat_half_well", |b| {
        b.iter(|| {
            let f = sensor
                .frame_fast(black_box(&st), 1, std::mem::take(&mut codes))
                .unwrap();
            codes = f.codes.data;
        })
    });
    g.finish();
    let mut g = cr.benchmark_group("frame_exact");
    g.sample_size(10);
    g.bench_function("flat_half_well", |b| {
        b.iter(|| black_box(sensor.frame_codes(black_box(&st), 1).unwrap()))
    });
    g.finish();
    let mut g = cr.benchmark_group("noise");
    g.sample_size(10);
    let key = fast::NoiseKey::new(1, 2, 3);
    g.bench_function("normal_5M", |b| {
        b.iter(|| {
            let mut acc = 0f32;
            for i in 0..(w * h) as u32 {
                acc += fast::normal_from_bits(key.bits(i));
            }
            black_box(acc)
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
