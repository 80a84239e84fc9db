//! Real IMX250MZR frames (8-bit PNG mosaics from polanalyser, MIT). They are never copied into
//! the repository: the test reads `../shared/data/real-imx250mzr` relative to the crate root
//! (also `../../shared/...`, for worktrees one level deeper) and skips, saying so, when absent.

use psns::demosaic::{self, Method};
use psns::image::Image;
use psns::sensor::mosaic::MosaicLayout;
use psns::stokes::circular_mean_aolp_deg;
use std::path::PathBuf;

fn data_dir() -> Option<PathBuf> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    [
        "../shared/data/real-imx250mzr",
        "../../shared/data/real-imx250mzr",
    ]
    .iter()
    .map(|p| root.join(p))
    .find(|p| p.join("polarizer.png").is_file())
}

fn read_gray8(path: &std::path::Path) -> Image<u8> {
    let f = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut reader = png::Decoder::new(f).read_info().unwrap();
    let mut buf = vec![0u8; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Grayscale);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    buf.truncate(info.buffer_size());
    Image::from_vec(info.width as usize, info.height as usize, buf)
}

/// Filter ROIs (rows, cols) chosen by eye inside the four filter discs of polarizer.png
/// (labels 0, 45, 90, 135 from left to right), away from the rims.
const ROIS: [((usize, usize), (usize, usize)); 4] = [
    ((1000, 1180), (290, 470)),
    ((1010, 1190), (910, 1090)),
    ((1010, 1190), (1466, 1646)),
    ((1020, 1200), (2020, 2200)),
];
const EXPECTED: [f64; 4] = [83.0, 44.0, 175.0, 135.0];

#[test]
fn polarizer_filters_read_their_angles_with_every_method() {
    let Some(dir) = data_dir() else {
        crate::common::missing(
            "polarizer_filters_read_their_angles_with_every_method",
            "../shared/data/real-imx250mzr not found; real-frame test not run",
        );
        return;
    };
    let raw = read_gray8(&dir.join("polarizer.png"));
    assert_eq!((raw.width, raw.height), (2448, 2048));
    for m in Method::ALL {
        let pi = demosaic::full_chain(&raw, MosaicLayout::IMX250MZR, m).unwrap();
        let mut got = [0f64; 4];
        for (k, ((r0, r1), (c0, c1))) in ROIS.iter().enumerate() {
            let vals = (*r0..*r1).flat_map(|r| (*c0..*c1).map(move |c| (r, c)));
            let a =
                circular_mean_aolp_deg(vals.map(|(r, c)| *pi.aolp_deg.get(r, c) as f64)).unwrap();
            got[k] = a;
            let e = psns::angle::SensorAngle::from_deg(a)
                .diff(psns::angle::SensorAngle::from_deg(EXPECTED[k]));
            assert!(
                e < 2.0,
                "{m}: filter {k} reads {a:.2} deg, expected {}",
                EXPECTED[k]
            );
        }
        println!(
            "{m:>10}: filters read {:.2} {:.2} {:.2} {:.2} deg",
            got[0], got[1], got[2], got[3]
        );
    }
}

#[test]
fn every_method_runs_on_every_real_frame() {
    let Some(dir) = data_dir() else {
        crate::common::missing(
            "every_method_runs_on_every_real_frame",
            "../shared/data/real-imx250mzr not found; real-frame test not run",
        );
        return;
    };
    for name in ["camera.png", "carps.png", "fruits.png", "polarizer.png"] {
        let full = read_gray8(&dir.join(name));
        // a 512 x 512 crop at an even offset keeps the mosaic phase
        let (r0, c0) = (768, 968);
        let mut crop = Image::<u8>::new(512, 512);
        for r in 0..512 {
            crop.data[r * 512..(r + 1) * 512].copy_from_slice(&full.row(r0 + r)[c0..c0 + 512]);
        }
        let mean_raw = crop.data.iter().map(|&v| v as f64).sum::<f64>() / crop.data.len() as f64;
        for m in Method::ALL {
            let pi = demosaic::full_chain(&crop, MosaicLayout::IMX250MZR, m).unwrap();
            let st = &pi.stokes;
            assert!(st
                .s0
                .data
                .iter()
                .chain(&st.s1.data)
                .chain(&st.s2.data)
                .all(|v| v.is_finite()));
            assert!(pi.aolp_deg.data.iter().all(|a| (0.0..180.0).contains(a)));
            // S0 is twice the mean sample (up to border effects)
            let mean_s0 =
                st.s0.data.iter().map(|&v| v as f64).sum::<f64>() / st.s0.data.len() as f64;
            assert!(
                (mean_s0 / (2.0 * mean_raw) - 1.0).abs() < 0.01,
                "{name} {m}: {mean_s0} vs {mean_raw}"
            );
        }
    }
}
