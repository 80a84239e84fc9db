//! The fused sensor kernel at full size (2448 x 2048): `cargo bench --bench sensor`.
//! `frame_fast/*` = sensor-frame Stokes rows → 12-bit codes (optics, polarizer, PRNU, dark
//! current, shot and read noise, DSNU, full well, ADC); `frame_exact` = the exact path.
//! `noise/normal_5M` = 5 M normal deviates from the counter-based generator, one thread.
//! `pack/*` = a full frame of 12-bit codes into each payload format.

use criterion::{criterion_group, criterion_main, Criterion};
use psns::camera::Intrinsics;
use psns::sensor::{self, normal, packing, FrameOptions, Radiance, Sensor, SensorConfig};
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
            let opts = FrameOptions::fast().into_codes(std::mem::take(&mut codes));
            let f = sensor
                .frame(Radiance::Planes(black_box(&st)), 1, opts)
                .unwrap();
            codes = f.codes.data;
        })
    });
    g.finish();
    let mut g = cr.benchmark_group("frame_exact");
    g.sample_size(10);
    g.bench_function("flat_half_well", |b| {
        b.iter(|| {
            let st = Radiance::Planes(black_box(&st));
            black_box(sensor.frame(st, 1, FrameOptions::exact()).unwrap())
        })
    });
    g.finish();
    let mut g = cr.benchmark_group("noise");
    g.sample_size(10);
    let key = normal::NoiseKey::new(1, 2, 3);
    g.bench_function("normal_5M", |b| {
        b.iter(|| {
            let mut acc = 0f32;
            for i in 0..(w * h) as u32 {
                acc += normal::normal_from_bits(key.bits(i / w as u32, i % w as u32));
            }
            black_box(acc)
        })
    });
    g.finish();
    let codes: Vec<u16> = (0..(w * h) as u32)
        .map(|k| (k.wrapping_mul(2_654_435_761) >> 20) as u16)
        .collect();
    let mut out = Vec::new();
    let mut g = cr.benchmark_group("pack");
    for f in packing::PixelFormat::ALL {
        g.bench_function(f.to_string(), |b| {
            b.iter(|| packing::pack(black_box(&codes), 12, f, false, &mut out).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
