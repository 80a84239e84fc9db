//! Uniform polarized fields round-trip through every method on every layout, and a wrong layout
//! gives the predicted channel permutation (spec `demosaic.md` §5).

use psns::demosaic::{self, mosaic_from_stokes, Method};
use psns::image::{Image, StokesImage};
use psns::sensor::mosaic::MosaicLayout;

const W: usize = 24;
const H: usize = 20;
const BORDER: usize = 4;

fn uniform(s0: f32, dolp: f32, aolp_deg: f32) -> StokesImage {
    let mut st = StokesImage::zeros(W, H);
    let t = (2.0 * aolp_deg as f64).to_radians();
    let (s1, s2) = (
        (s0 as f64 * dolp as f64 * t.cos()) as f32,
        (s0 as f64 * dolp as f64 * t.sin()) as f32,
    );
    st.s0.data.fill(s0);
    st.s1.data.fill(s1);
    st.s2.data.fill(s2);
    st
}

/// Max |difference| over the interior, relative to `scale`.
fn max_err(a: &Image<f32>, b: &Image<f32>, scale: f32) -> f32 {
    let mut m = 0f32;
    for r in BORDER..H - BORDER {
        for c in BORDER..W - BORDER {
            m = m.max((a.get(r, c) - b.get(r, c)).abs() / scale);
        }
    }
    m
}

#[test]
fn uniform_fields_round_trip_all_methods_all_layouts() {
    let s0 = 1000.0f32;
    let mut worst = 0f32;
    let mut worst_aolp = 0f64;
    for layout in MosaicLayout::all() {
        for dolp in [0.0f32, 0.5, 1.0] {
            for step in 0..=12 {
                let aolp = step as f32 * 15.0;
                let truth = uniform(s0, dolp, aolp);
                let raw = mosaic_from_stokes(&truth, layout);
                for m in Method::ALL {
                    let pi = demosaic::full_chain(&raw, layout, m).unwrap();
                    let st = &pi.stokes;
                    for (e, t) in [
                        (&st.s0, &truth.s0),
                        (&st.s1, &truth.s1),
                        (&st.s2, &truth.s2),
                    ] {
                        let err = max_err(e, t, s0);
                        assert!(
                            err <= 1e-6,
                            "{m} {layout} dolp {dolp} aolp {aolp}: rel err {err}"
                        );
                        worst = worst.max(err);
                    }
                    for r in BORDER..H - BORDER {
                        for c in BORDER..W - BORDER {
                            let d = *pi.dolp.get(r, c);
                            assert!((d - dolp).abs() <= 2e-6, "{m} {layout}: dolp {d} vs {dolp}");
                            if dolp > 0.0 {
                                let a = *pi.aolp_deg.get(r, c) as f64;
                                let e = psns::angle::SensorAngle::from_deg(a)
                                    .diff(psns::angle::SensorAngle::from_deg(aolp as f64));
                                assert!(e < 1e-3, "{m} {layout}: aolp {a} vs {aolp}");
                                worst_aolp = worst_aolp.max(e);
                            }
                        }
                    }
                }
            }
        }
    }
    println!("uniform fields: worst relative Stokes error {worst:e}, worst AoLP error {worst_aolp:e} deg");
}

/// Integer-valued fields through u8 and u16 (8, 10, 12, 16-bit codes): bit-exact Stokes.
#[test]
fn integer_inputs_are_bit_exact() {
    let layout = MosaicLayout::IMX250MZR;
    for (s0, bits) in [(200.0f32, 8u32), (800.0, 10), (4000.0, 12), (60000.0, 16)] {
        for aolp in [0.0f32, 45.0, 90.0, 135.0] {
            for dolp in [0.5f32, 1.0] {
                let mut truth = uniform(s0, dolp, aolp);
                // exact integer Stokes (cos/sin of multiples of 90° leave 1e-16 residues)
                for p in [&mut truth.s1, &mut truth.s2] {
                    p.data.iter_mut().for_each(|v| *v = v.round());
                }
                let rawf = mosaic_from_stokes(&truth, layout);
                assert!(rawf
                    .data
                    .iter()
                    .all(|v| v.fract() == 0.0 && *v < (1u32 << bits) as f32));
                let r16 = Image::from_vec(W, H, rawf.data.iter().map(|v| *v as u16).collect());
                for m in Method::ALL {
                    let st = demosaic::demosaic(&r16, layout, m).unwrap();
                    assert!(max_err(&st.s0, &truth.s0, 1.0) == 0.0, "{m} u16 {bits} bit");
                    assert!(max_err(&st.s1, &truth.s1, 1.0) == 0.0, "{m} u16 {bits} bit");
                    assert!(max_err(&st.s2, &truth.s2, 1.0) == 0.0, "{m} u16 {bits} bit");
                    if bits == 8 {
                        let r8 =
                            Image::from_vec(W, H, rawf.data.iter().map(|v| *v as u8).collect());
                        let st8 = demosaic::demosaic(&r8, layout, m).unwrap();
                        assert_eq!(st8, st, "{m}: u8 and u16 differ");
                    }
                }
            }
        }
    }
}

/// Decoding with the wrong layout permutes the channels exactly as predicted: for each of the 24
/// assumed layouts the output equals the Stokes vector of the permuted channel intensities.
#[test]
fn wrong_layout_gives_predicted_permutation() {
    let truth_layout = MosaicLayout::IMX250MZR;
    let (s0, dolp, aolp) = (1000.0f32, 0.6f32, 20.0f32);
    let truth = uniform(s0, dolp, aolp);
    let raw = mosaic_from_stokes(&truth, truth_layout);
    let t = (2.0 * aolp as f64).to_radians();
    let intensity = |k: usize| {
        let th = (2.0 * k as f64 * 45.0).to_radians();
        0.5 * (s0 as f64 + (s0 * dolp) as f64 * (t.cos() * th.cos() + t.sin() * th.sin()))
    };
    let mut maps = std::collections::BTreeSet::new();
    let [a, b, c, d] = truth_layout.channels();
    let dihedral = [
        [a, b, c, d],
        [c, a, d, b],
        [d, c, b, a],
        [b, d, a, c],
        [b, a, d, c],
        [c, d, a, b],
        [a, c, b, d],
        [d, b, c, a],
    ];
    for assumed in MosaicLayout::all() {
        // channel k of the assumed layout sits where the true layout has channel pi(k)
        let pi = |k: usize| {
            let (r, c) = assumed.position_of(k);
            truth_layout.channel(r, c)
        };
        let i: Vec<f64> = (0..4).map(|k| intensity(pi(k))).collect();
        let (p1, p2) = (i[0] - i[2], i[1] - i[3]);
        for m in [Method::Superpixel, Method::Bilinear, Method::Eari] {
            let st = demosaic::demosaic(&raw, assumed, m).unwrap();
            for rc in [(6, 6), (7, 9), (10, 13)] {
                let (e1, e2) = (*st.s1.get(rc.0, rc.1) as f64, *st.s2.get(rc.0, rc.1) as f64);
                assert!(
                    (e1 - p1).abs() < 1e-3 && (e2 - p2).abs() < 1e-3,
                    "{m} {assumed}: ({e1}, {e2}) vs ({p1}, {p2})"
                );
            }
        }
        let a = psns::angle::SensorAngle::from_stokes(p1, p2).deg();
        let ch = assumed.channels();
        if dihedral.contains(&ch) {
            maps.insert((a * 1000.0).round() as i64);
        }
        if assumed == truth_layout {
            assert!((a - aolp as f64).abs() < 1e-9);
        }
    }
    // the 8 rotations/reflections of the pattern give 8 distinct AoLP readings (spec §5)
    assert_eq!(maps.len(), 8, "{maps:?}");
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let tiny = Image::<u16>::new(4, 4);
    for m in Method::ALL {
        assert!(demosaic::demosaic(&tiny, MosaicLayout::IMX250MZR, m).is_err());
    }
    let broken = Image {
        width: 16,
        height: 16,
        data: vec![0u16; 10],
    };
    assert!(demosaic::full_chain(&broken, MosaicLayout::IMX250MZR, Method::Bilinear).is_err());
}

#[test]
fn superpixel_half_resolution_planes() {
    let truth = uniform(1000.0, 0.4, 75.0);
    let raw = mosaic_from_stokes(&truth, MosaicLayout::IMX250MZR);
    let half = demosaic::superpixel_half(&raw, MosaicLayout::IMX250MZR).unwrap();
    assert_eq!((half.width(), half.height()), (W / 2, H / 2));
    assert!((half.s1.data[5] - truth.s1.data[0]).abs() < 1e-3);
    assert!((half.s2.data[5] - truth.s2.data[0]).abs() < 1e-3);
}
