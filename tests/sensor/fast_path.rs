//! The fast path against its targets: Poisson statistics of the shot noise, read noise
//! folded in, frames independent of the thread count, and the fast model's means against the
//! exact path's over a sweep of skies.

use psns::camera::{Attitude, Camera, Intrinsics};
use psns::image::StokesImage;
use psns::render::{self, SkyGrid, StokesOptions};
use psns::sensor::{self, Exposure, FrameOptions, Radiance, Sensor, SensorConfig, Stages};
use psns::sky::{Sky, SkyParams};
use psns::sun::SunPosition;

const N: usize = 512;

/// A flat, unpolarized field giving `mean_e` electrons per pixel in the ideal model.
fn flat_for_mean(s: &Sensor, mean_e: f64, t_us: f64) -> StokesImage {
    let probe = sensor::flat_field(N, N, 1.0, 0.0, 0.0).unwrap();
    let rate = s.electron_rate(&probe).unwrap()[0];
    sensor::flat_field(N, N, mean_e / (rate * t_us * 1e-6), 0.0, 0.0).unwrap()
}

/// Camera at 24 dB (6.2 DN per e⁻) with only shot noise (and optionally read noise) on, black
/// level 100 DN with read noise.
fn quiet_sensor(read: bool) -> (Sensor, f64) {
    let mut cfg = SensorConfig {
        gain_db: 24.0,
        black_level_dn: if read { 100.0 } else { 0.0 },
        exposure: Exposure::Fixed { us: 1000.0 },
        ..SensorConfig::default()
    };
    cfg.stages = Stages {
        shot: true,
        fwc_clip: true,
        quantize: true,
        read,
        polarizer_er: true,
        ..Stages::none()
    };
    let s = Sensor::new(&cfg, &Intrinsics::with_size(N, N), 5).unwrap();
    let k = psns::sensor::adc::system_gain(cfg.k0, cfg.gain_db);
    (s, k)
}

/// Mean, variance and skewness of the electrons (codes − black) / k, rounded to whole
/// electrons when `whole` (k > 2 DN per e⁻ makes that exact; otherwise the ADC's rounding
/// distorts the lattice by up to 0.5 DN and the variance by a few per cent at 2 e⁻).
fn moments(codes: &[u16], k: f64, black: f64, whole: bool) -> (f64, f64, f64) {
    let n = codes.len() as f64;
    let e: Vec<f64> = codes
        .iter()
        .map(|&c| {
            let e = (c as f64 - black) / k;
            if whole {
                e.round()
            } else {
                e
            }
        })
        .collect();
    let m = e.iter().sum::<f64>() / n;
    let v = e.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n;
    let s3 = e.iter().map(|x| (x - m).powi(3)).sum::<f64>() / n;
    (m, v, s3 / v.powf(1.5))
}

#[test]
fn shot_noise_is_poisson_in_whole_electrons() {
    let (s, k) = quiet_sensor(false);
    assert!(k > 6.0);
    for mean in [2.0f64, 5.0, 20.0, 100.0, 500.0] {
        let st = flat_for_mean(&s, mean, 1000.0);
        for (name, f) in [
            (
                "fast",
                s.frame(Radiance::Planes(&st), 3, FrameOptions::fast())
                    .unwrap(),
            ),
            (
                "exact",
                s.frame(Radiance::Planes(&st), 3, FrameOptions::exact())
                    .unwrap(),
            ),
        ] {
            // whole electrons: every code is the rounded image of an integer
            let off = f
                .codes
                .data
                .iter()
                .map(|&c| {
                    let e = c as f64 / k;
                    (e - e.round()).abs()
                })
                .fold(0f64, f64::max);
            assert!(
                off <= 0.5 / k + 1e-9,
                "{name} μ {mean}: {off} e⁻ off an integer"
            );
            let (m, v, g) = moments(&f.codes.data, k, 0.0, true);
            eprintln!("{name} μ {mean}: mean {m:.4} variance {v:.4} skewness {g:.4}");
            assert!((m / mean - 1.0).abs() < 0.02, "{name} μ {mean}: mean {m}");
            assert!(
                (v / mean - 1.0).abs() < 0.03,
                "{name} μ {mean}: variance {v}"
            );
            let want = 1.0 / mean.sqrt();
            assert!(
                (g - want).abs() < 0.03,
                "{name} μ {mean}: skewness {g} vs {want}"
            );
        }
    }
}

#[test]
fn read_noise_folded_keeps_the_first_three_cumulants() {
    let (s, k) = quiet_sensor(true);
    let sr = s.config().read_noise_e;
    for mean in [0.5f64, 20.0, 300.0] {
        let st = flat_for_mean(&s, mean, 1000.0);
        let f = s
            .frame(Radiance::Planes(&st), 4, FrameOptions::fast())
            .unwrap();
        // a black level of 16 e⁻ (6.5 σ of the read noise) so that no code clips at 0
        let (m, v, g) = moments(&f.codes.data, k, f.black_level_dn, false);
        let var = mean + sr * sr;
        assert!((m - mean).abs() < 0.05 + 0.02 * mean, "μ {mean}: mean {m}");
        assert!(
            (v / var - 1.0).abs() < 0.03,
            "μ {mean}: variance {v} vs {var}"
        );
        let want = mean / var.powf(1.5);
        assert!((g - want).abs() < 0.03, "μ {mean}: skewness {g} vs {want}");
    }
}

#[test]
fn frames_do_not_depend_on_the_thread_count() {
    let cfg = SensorConfig::default();
    let s = Sensor::new(&cfg, &Intrinsics::with_size(N, N), 9).unwrap();
    let st = sensor::flat_field(N, N, 0.04, 0.3, 20.0).unwrap();
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                s.frame(Radiance::Planes(&st), 7, FrameOptions::fast())
                    .unwrap()
                    .codes
                    .data
            })
    };
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, run(3));
    // and a different frame index is different noise
    let other = s
        .frame(Radiance::Planes(&st), 8, FrameOptions::fast())
        .unwrap()
        .codes
        .data;
    assert!(one.iter().zip(&other).filter(|(a, b)| a != b).count() > N * N / 2);
}

/// The codes' CRC-32, taken band by band in the sensor pass and combined, is the CRC of the
/// whole frame's little-endian bytes, on sizes whose last band is short, at any thread count;
/// without the request there is none.
#[test]
fn band_crc_is_the_frame_crc() {
    let cfg = SensorConfig::default();
    for (w, h) in [(64usize, 16usize), (52, 36), (36, 4), (128, 132)] {
        let s = Sensor::new(&cfg, &Intrinsics::with_size(w, h), 9).unwrap();
        let st = sensor::flat_field(w, h, 0.04, 0.3, 20.0).unwrap();
        assert_eq!(
            s.frame(Radiance::Planes(&st), 7, FrameOptions::fast())
                .unwrap()
                .codes_crc32,
            None
        );
        for threads in [1, 3] {
            let f = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| {
                    s.frame(
                        Radiance::Planes(&st),
                        7,
                        FrameOptions::fast().with_sink(sensor::FastSink::CodesCrc32),
                    )
                    .unwrap()
                });
            let bytes: Vec<u8> = f.codes.data.iter().flat_map(|c| c.to_le_bytes()).collect();
            let want = cfg!(target_endian = "little").then(|| crc32fast::hash(&bytes));
            assert_eq!(f.codes_crc32, want, "{w} x {h}, {threads} threads");
        }
    }
}

/// Fast vs exact means with temporal noise off for one camera over sun zeniths x turbidities x
/// views (yaw offset from the sun, pitch below it): below a tenth of the shot noise at every
/// pixel outside the solar disc, and below 1 DN where the shot noise is under 10 DN; fast and
/// exact agree on which pixels are dark (ground without radiance, outside a fisheye's image
/// circle). Returns the worst difference in shot-noise σ and where.
fn fast_vs_exact(
    intr: Intrinsics,
    zeniths: &[f64],
    turbidities: &[f64],
    views: &[(f64, f64)],
    absolute_pitch: bool,
) -> (f64, String) {
    let cfg = SensorConfig::default();
    let s = Sensor::new(&cfg, &intr, 1).unwrap();
    let t = 1e-3;
    let k = psns::sensor::adc::system_gain(cfg.k0, cfg.gain_db);
    let tol = 0.025 / cfg.full_well_e.sqrt();
    let mut worst = (0f64, String::new());
    for &zenith in zeniths {
        for &turbidity in turbidities {
            let sun = SunPosition::new(zenith, 120.0);
            let sky = Sky::new(
                sun,
                &SkyParams {
                    turbidity,
                    ..SkyParams::default()
                },
            )
            .unwrap();
            for &(dy, dp) in views {
                let pitch = if absolute_pitch {
                    dp
                } else {
                    (90.0 - zenith - dp).clamp(-10.0, 90.0)
                };
                let att = Attitude::enu(120.0 + dy, pitch, 0.0);
                let cam = Camera::new(intr, &att, sun.azimuth_deg).unwrap();
                let opts = StokesOptions { sun_disc: true };
                let (exact, _) = render::render_stokes(&sky, &cam, opts);
                let grid = SkyGrid::new(&sky, &cam, opts, 16, tol);
                let re = s.electron_rate(&exact).unwrap();
                let rf = s.electron_rate_fast(&grid).unwrap();
                let sun_c = cam.enu_to_camera * sun.vector();
                for r in 0..intr.height {
                    for c in 0..intr.width {
                        let i = r * intr.width + c;
                        let Some(d) = cam.intrinsics.ray(c as f64, r as f64) else {
                            continue;
                        };
                        let d = d.normalize();
                        // the solar disc and the 2 IFOV it is spread over
                        let ifov = (intr.pixel_pitch_um * 1e-3 / intr.focal_length_mm).to_degrees();
                        let disc = if intr.projection == psns::camera::Projection::Rectilinear {
                            0.27 + 0.11
                        } else {
                            0.27 + 2.0 * ifov
                        };
                        if d.dot(sun_c).clamp(-1.0, 1.0).acos().to_degrees() < disc {
                            continue;
                        }
                        // the fast path's gain quantum is absolute (3e-5): where a fisheye's
                        // RI falls below 0.01 near the rim it is 0.3 % of this test's 1 ms
                        // signal, unphysically bright there (over 10^5 e⁻ before the falloff);
                        // at an exposure within the full well it stays below 0.04 σ
                        if cfg.ri.factor(&intr, c as f64, r as f64) < 0.01 {
                            continue;
                        }
                        let (me, mf) = (re[i] * t, rf[i] * t);
                        // dark stays dark (the fast path's 16-bit RI map may round the last
                        // hundredths of an electron at a fisheye's rim to 0)
                        assert!(me != 0.0 || mf == 0.0, "pixel {c},{r}: {me} vs {mf} e⁻");
                        let sd = me.sqrt();
                        let bad = if k * sd < 10.0 {
                            k * (mf - me).abs() >= 1.0
                        } else {
                            (mf - me).abs() >= 0.1 * sd
                        };
                        let rel = (mf - me).abs() / sd.max(1e-9);
                        if rel > worst.0 {
                            worst = (rel, format!("zenith {zenith} T {turbidity} view {dy},{dp} pixel {c},{r}: {me} vs {mf} e⁻"));
                        }
                        assert!(!bad, "zenith {zenith} T {turbidity} view {dy},{dp} pixel {c},{r}: exact {me} e⁻, fast {mf} e⁻");
                    }
                }
            }
        }
    }
    worst
}

/// Fast vs exact means over sun zenith x turbidity x attitudes that keep the sun in view (look
/// at the sun, beside it, and away from it).
#[test]
fn fast_means_match_the_exact_path() {
    let worst = fast_vs_exact(
        Intrinsics::with_size(612, 512),
        &[0.0, 30.0, 60.0, 88.0],
        &[2.0, 4.0, 8.0],
        &[(0.0, 0.0), (8.0, 5.0), (60.0, 20.0)],
        false,
    );
    eprintln!(
        "largest fast-exact difference: {:.4} shot-noise σ ({})",
        worst.0, worst.1
    );
}

/// The same through a 1.8 mm equidistant fisheye (the whole sky in a circle of 205 px at 4x
/// binning) with either lens: looking at the zenith (the horizon is the image circle's rim) and
/// pitched 40° and 60° (the horizon crosses the circle), the grid keeps both edges exact.
#[test]
fn fast_means_match_the_exact_path_through_a_fisheye() {
    for lens in psns::camera::Lens::ALL {
        let intr = Intrinsics {
            projection: psns::camera::Projection::Equidistant,
            lens: Some(lens),
            focal_length_mm: 1.8,
            pixel_pitch_um: 3.45 * 4.0,
            ..Intrinsics::with_size(612, 512)
        };
        let worst = fast_vs_exact(
            intr,
            &[30.0, 70.0, 88.0],
            &[4.0],
            &[(0.0, 0.0), (30.0, 40.0), (90.0, 60.0)],
            true,
        );
        eprintln!(
            "{lens}: largest fast-exact difference: {:.4} shot-noise σ ({})",
            worst.0, worst.1
        );
    }
}
