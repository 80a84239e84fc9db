//! `psns demosaic` and `psns bench demosaic` end to end (quick mode), the scoring helpers, and
//! the spec §4 noise laws for the superpixel estimator.

use super::demosaic::{
    bench_demosaic, noise_sweep, saturation_mask, saturation_threshold, score_masked, BenchOptions,
    CSV_HEADER, MAX_FILE_BYTES,
};
use super::scenes::{self, Scene};
use crate::cli::demosaic::{demosaic_to_dir, DemosaicOptions};
use psns::demosaic::{full_chain, Method};
use psns::image::{Image, StokesImage};
use psns::sensor::mosaic::MosaicLayout;
use std::collections::HashMap;

#[test]
fn quick_bench_writes_table_chart_and_maps() {
    let dir = tempfile::tempdir().unwrap();
    let files = bench_demosaic(&BenchOptions {
        out: dir.path().to_path_buf(),
        runs: 1,
        quick: true,
    })
    .unwrap();
    for name in [
        "demosaic.csv",
        "demosaic_speed_accuracy.svg",
        "demosaic_aolp_error_occluder-edge.png",
        "demosaic_aolp_error_sun-in-view.png",
        "demosaic_noise.csv",
        "demosaic_noise.svg",
    ] {
        let p = dir.path().join(name);
        assert!(
            files.iter().any(|f| f.ends_with(name)),
            "{name} not reported"
        );
        let n = std::fs::metadata(&p).unwrap().len() as usize;
        assert!(n > 500 && n < MAX_FILE_BYTES, "{name}: {n} bytes");
    }
    let csv = std::fs::read_to_string(dir.path().join("demosaic.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header.join(","), CSV_HEADER);
    for col in [
        "method",
        "scene",
        "ms_per_frame",
        "s0_psnr_db",
        "dolp_rmse",
        "aolp_rmse_deg",
    ] {
        assert!(header.contains(&col), "missing column {col}");
    }
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    // (method, scene, bits) -> row
    let mut rows: HashMap<(String, String, String), Vec<String>> = HashMap::new();
    for l in lines {
        let f: Vec<String> = l.split(',').map(str::to_string).collect();
        assert_eq!(f.len(), header.len(), "{l}");
        rows.insert((f[0].clone(), f[1].clone(), f[2].clone()), f);
    }
    assert_eq!(rows.len(), Method::ALL.len() * (Scene::ALL.len() + 1));
    let get = |m: Method, s: Scene, bits: &str, c: &str| -> f64 {
        rows[&(m.name().to_string(), s.name().to_string(), bits.to_string())][col(c)]
            .parse()
            .unwrap()
    };
    for m in Method::ALL {
        for s in Scene::ALL {
            assert!(get(m, s, "12", "ms_per_frame") > 0.0);
            let a = get(m, s, "12", "aolp_rmse_deg");
            assert!(a.is_finite() && a > 0.0 && a < 30.0, "{m} {s}: {a}");
            assert!(get(m, s, "12", "s0_psnr_db") > 20.0);
        }
        // the sun scene clips; the clipped neighbourhood is excluded and costs AoLP accuracy
        assert!(get(m, Scene::SunInView, "12", "n_sat_excluded_px") > 0.0);
        assert!(
            get(m, Scene::SunInView, "12", "aolp_rmse_all_deg")
                > get(m, Scene::SunInView, "12", "aolp_rmse_deg")
        );
        assert_eq!(get(m, Scene::ClearSky, "12", "n_sat_excluded_px"), 0.0);
    }
    // spec §2 ordering at the occluder edge: superpixel is the worst method
    let sp = get(
        Method::Superpixel,
        Scene::OccluderEdge,
        "12",
        "aolp_rmse_deg",
    );
    for m in [Method::Bilinear, Method::Ppid, Method::Eari] {
        let v = get(m, Scene::OccluderEdge, "12", "aolp_rmse_deg");
        assert!(v < sp, "{m} {v} vs superpixel {sp}");
    }
    // low light and low DoLP are harder than the clear sky for every method
    for m in Method::ALL {
        let c = get(m, Scene::ClearSky, "12", "aolp_rmse_deg");
        assert!(
            get(m, Scene::LowLight, "12", "aolp_rmse_deg") > 1.5 * c,
            "{m}"
        );
        assert!(
            get(m, Scene::Turbid, "12", "aolp_rmse_deg") > 1.5 * c,
            "{m}"
        );
    }
    // the chart has real text (plotters SVG without the ttf feature)
    let svg = std::fs::read_to_string(dir.path().join("demosaic_speed_accuracy.svg")).unwrap();
    assert!(svg.contains("<text"));
    for m in Method::ALL {
        assert!(svg.contains(&format!(">{}<", m.name())) || svg.contains(m.name()));
    }
    assert!(svg.contains("occluder-edge") && svg.contains("AoLP RMSE"));
}

#[test]
fn superpixel_noise_laws_within_ten_percent() {
    // DoLP bias at p = 0: 0.886/sqrt(N) (read noise 2.5 e- adds 6.25/N to the variance: N >= 300)
    let bias = noise_sweep(
        128,
        &[300.0, 1000.0, 3000.0, 10000.0],
        0.0,
        &[Method::Superpixel, Method::Bilinear],
        5,
    )
    .unwrap();
    for r in bias.iter().filter(|r| r.method == Method::Superpixel) {
        let ratio = r.mean_dolp / r.theory_bias;
        assert!(
            (ratio - 1.0).abs() < 0.10,
            "N {}: bias {} vs {}",
            r.electrons,
            r.mean_dolp,
            r.theory_bias
        );
    }
    // bilinear averages more samples: clearly below the superpixel law (the check can fail)
    for r in bias.iter().filter(|r| r.method == Method::Bilinear) {
        assert!(
            r.mean_dolp < 0.85 * r.theory_bias,
            "bilinear N {}: {}",
            r.electrons,
            r.mean_dolp
        );
    }
    // sigma_AoLP at p = 0.1 where p sqrt(N) >= 3: 20.3 deg / (p sqrt(N))
    let sig = noise_sweep(
        128,
        &[1000.0, 3000.0, 10000.0],
        0.1,
        &[Method::Superpixel],
        6,
    )
    .unwrap();
    for r in &sig {
        assert!(0.1 * r.electrons.sqrt() >= 3.0);
        let ratio = r.aolp_sigma_deg / r.theory_sigma_deg;
        assert!(
            (ratio - 1.0).abs() < 0.10,
            "N {}: sigma {} vs {}",
            r.electrons,
            r.aolp_sigma_deg,
            r.theory_sigma_deg
        );
    }
}

#[test]
fn saturation_mask_dilates_and_masked_score_matches_plain() {
    let mut codes = Image::<u16>::new(16, 12);
    *codes.get_mut(5, 7) = 4095;
    let m = saturation_mask(&codes, 4095, 2);
    assert_eq!(m.iter().filter(|&&v| v).count(), 25);
    assert!(m[3 * 16 + 5] && m[7 * 16 + 9] && !m[2 * 16 + 7] && !m[5 * 16 + 10]);
    // a full well reads a few DN below the top code: it seeds the mask too
    assert_eq!(saturation_threshold(12), 4091);
    assert_eq!(saturation_threshold(8), 255);
    assert_eq!(saturation_threshold(10), 1022);
    assert_eq!(saturation_threshold(16), 65535 - 64);
    let mut codes = Image::<u16>::new(16, 12);
    *codes.get_mut(5, 7) = 4092;
    *codes.get_mut(9, 2) = 4090;
    let m = saturation_mask(&codes, saturation_threshold(12), 1);
    assert_eq!(m.iter().filter(|&&v| v).count(), 9);
    assert!(m[5 * 16 + 7] && !m[9 * 16 + 2]);

    let (w, h) = (40, 32);
    let mut t = StokesImage::zeros(w, h);
    let mut e = StokesImage::zeros(w, h);
    for k in 0..w * h {
        let x = k as f32;
        t.s0.data[k] = 1000.0 + (x * 0.37).sin() * 200.0;
        t.s1.data[k] = 300.0 * (x * 0.11).cos();
        t.s2.data[k] = 250.0 * (x * 0.07).sin();
        e.s0.data[k] = t.s0.data[k] + 5.0 * (x * 1.3).sin();
        e.s1.data[k] = t.s1.data[k] + 20.0 * (x * 0.9).cos();
        e.s2.data[k] = t.s2.data[k] - 15.0 * (x * 0.5).sin();
    }
    let a = score_masked(&e, &t, 4095.0, 0.05, 4, None).unwrap();
    let b = psns::stokes::score(&e, &t, 4095.0, 0.05, 4).unwrap();
    assert!((a.s0_psnr_db - b.s0_psnr_db).abs() < 1e-9);
    assert!((a.dolp_rmse - b.dolp_rmse).abs() < 1e-12);
    assert!((a.aolp_rmse_deg - b.aolp_rmse_deg).abs() < 1e-9);
    assert_eq!(a.n_aolp_pixels, b.n_aolp_pixels);
    // excluding half the frame changes the counts accordingly
    let mask: Vec<bool> = (0..w * h).map(|k| k / w < h / 2).collect();
    let c = score_masked(&e, &t, 4095.0, 0.05, 4, Some(&mask)).unwrap();
    assert_eq!(c.n_pixels, (w - 8) * (h / 2 - 4));
}

fn read(dir: &std::path::Path, name: &str) -> Image<f32> {
    psns::io::read_npy_f32(&dir.join(name)).unwrap()
}

#[test]
fn demosaic_command_reads_png_tiff_and_streams() {
    let sf = scenes::render(Scene::ClearSky, 64, 48, 12).unwrap();
    let codes = sf.frame.codes.clone();
    let layout = MosaicLayout::IMX250MZR;
    let want = full_chain(&codes, layout, Method::Bilinear).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("raw.png");
    psns::io::write_png_gray16(&png, &codes).unwrap();
    let tiff = dir.path().join("raw.tiff");
    psns::io::write_tiff_u16(&tiff, &codes).unwrap();
    for (input, sub) in [(&png, "png"), (&tiff, "tiff")] {
        let out = dir.path().join(sub);
        let files = demosaic_to_dir(&DemosaicOptions {
            input: input.clone(),
            method: Method::Bilinear,
            out: out.clone(),
            frame: None,
            layout,
            debias_sigma: None,
        })
        .unwrap();
        for n in [
            "s0.npy",
            "s1.npy",
            "s2.npy",
            "dolp.npy",
            "aolp.npy",
            "aolp.png",
            "dolp.png",
            "aolp_dolp.png",
        ] {
            assert!(files.iter().any(|f| f.ends_with(n)), "{n}");
        }
        assert_eq!(read(&out, "s1.npy"), want.stokes.s1);
        let a = read(&out, "aolp.npy");
        assert_eq!(a, want.aolp_deg);
        assert!(a.data.iter().all(|v| (0.0..180.0).contains(v)));
    }

    // a stream with two frames and a black level: frame 1 on request, frame 0 by default
    use psns::sensor::packing::PixelFormat;
    use psns::stream::{FileHeader, FrameMeta, StreamWriter};
    let hd = FileHeader {
        width: 64,
        height: 48,
        pixel_format: PixelFormat::Mono16,
        bits_valid: 12,
        layout: MosaicLayout::IMX250MZR,
        ..Default::default()
    };
    let mut wr = StreamWriter::new(Vec::new(), &hd).unwrap();
    let shifted: Vec<u16> = codes.data.iter().map(|&v| (v + 16).min(4095)).collect();
    for (i, c) in [&codes.data, &shifted].into_iter().enumerate() {
        let meta = FrameMeta {
            index: i as u64,
            black_level: if i == 1 { 16.0 } else { 0.0 },
            ..Default::default()
        };
        wr.write_frame(&meta, c).unwrap();
    }
    let stream = dir.path().join("s.psns");
    std::fs::write(&stream, wr.finish().unwrap()).unwrap();
    for frame in [None, Some(1)] {
        let out = dir.path().join(format!("stream{frame:?}"));
        demosaic_to_dir(&DemosaicOptions {
            input: stream.clone(),
            method: Method::Superpixel,
            out: out.clone(),
            frame,
            layout: MosaicLayout::IMX250MZR,
            debias_sigma: None,
        })
        .unwrap();
        let sp = full_chain(&codes, layout, Method::Superpixel).unwrap();
        let s0 = read(&out, "s0.npy");
        let worst = s0
            .data
            .iter()
            .zip(&sp.stokes.s0.data)
            .map(|(a, b)| (a - b).abs())
            .fold(0f32, f32::max);
        // frame 1 is frame 0 + 16 DN with black level 16 (up to clipping at 4095)
        assert!(worst < 1e-3, "frame {frame:?}: S0 differs by {worst}");
    }
    let bad = dir.path().join("bad.bin");
    std::fs::write(&bad, b"not a raw image at all").unwrap();
    assert!(demosaic_to_dir(&DemosaicOptions {
        input: bad,
        method: Method::Bilinear,
        out: dir.path().join("x"),
        frame: None,
        layout,
        debias_sigma: None,
    })
    .is_err());
}

#[test]
fn fused_superpixel_chain_matches_demosaic_then_stokes() {
    // odd sizes exercise the repeated last block; reused buffers of another size are refitted
    for (w, h) in [(64usize, 48usize), (37, 29)] {
        let data: Vec<u16> = (0..w * h)
            .map(|k| ((k * 7919 + k / w * 13) % 4000) as u16)
            .collect();
        let raw = Image::from_vec(w, h, data);
        let layout = MosaicLayout::IMX250MZR;
        let st = psns::demosaic::demosaic(&raw, layout, Method::Superpixel).unwrap();
        let (d, a) = psns::stokes::dolp_aolp_images(&st);
        let mut out = full_chain(&Image::<u16>::new(16, 16), layout, Method::Superpixel).unwrap();
        psns::demosaic::full_chain_into(&raw, layout, Method::Superpixel, &mut out).unwrap();
        assert_eq!(out.stokes, st);
        assert_eq!(out.dolp, d);
        assert_eq!(out.aolp_deg, a);
    }
}

#[test]
fn quick_into_docs_is_refused_before_anything_is_written() {
    use super::demosaic::inside_docs;
    use std::path::Path;
    for p in [
        "docs/bench",
        "./docs",
        "docs",
        "../psns/docs/bench",
        "/x/docs/y",
    ] {
        assert!(inside_docs(Path::new(p)), "{p}");
    }
    for p in ["out/bench", "/tmp/bench", "documents/bench", "docsx"] {
        assert!(!inside_docs(Path::new(p)), "{p}");
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("docs").join("bench");
    let e = bench_demosaic(&BenchOptions {
        out: out.clone(),
        runs: 1,
        quick: true,
    })
    .unwrap_err();
    assert!(e.is_usage(), "{e}");
    assert!(
        e.to_string().contains("quick numbers never land in docs"),
        "{e}"
    );
    assert!(!dir.path().join("docs").exists(), "something was written");
}
