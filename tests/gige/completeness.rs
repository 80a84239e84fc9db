//! Every sky model through `psns gige`, and a world: the first block Aravis receives is frame 0
//! of `psns stream` with the same options, byte for byte. A model the device forgets fails here.

use super::harness::*;
use psns::sky::PolarizationModel;

/// A small sensor: the device renders it quickly.
const SMALL: [&str; 4] = ["--width", "320", "--height", "256"];

/// The sha256 of the first Mono16 block of `psns gige SMALL OPTS`, and of frame 0 of
/// `psns stream SMALL OPTS` in Mono16 at 12 bits (the device's format for Mono16).
fn first_block_and_stream_frame(opts: &[&str]) -> (String, String) {
    let mut args = SMALL.to_vec();
    args.extend_from_slice(opts);
    let s = Server::start(&args);
    let lines = client(
        120,
        &["grab", &s.ip(), "--format", "Mono16", "--frames", "1"],
    );
    s.stop();
    let b = buffers(&lines);
    assert_eq!(b.len(), 1, "{opts:?}: {lines:?}");
    assert_eq!(b[0]["block"].as_u64(), Some(1), "{opts:?}");
    assert_eq!(b[0]["status"], "success", "{opts:?}");
    assert_eq!(b[0]["size"].as_u64(), Some(320 * 256 * 2), "{opts:?}");
    let want = stream_hashes(&args, &["--bit-depth", "12", "--pixel-format", "mono16"], 1);
    (
        b[0]["sha256"].as_str().unwrap().to_string(),
        want[0].clone(),
    )
}

/// Every polarization model: the device's first frame is the stream's frame 0, and the models
/// give different frames (so the option reaches the device).
#[test]
fn every_sky_model_through_gige_equals_stream_frame_0() {
    require_tools();
    let mut seen: Vec<(PolarizationModel, String)> = Vec::new();
    for m in PolarizationModel::ALL {
        let (got, want) = first_block_and_stream_frame(&["--model", m.name()]);
        assert_eq!(
            got, want,
            "{m}: psns gige's block 1 is not psns stream's frame 0"
        );
        for (other, h) in &seen {
            assert_ne!(&got, h, "{m} gives the frame of {other}");
        }
        seen.push((m, got));
    }
}

/// A world (a street canyon, seen through a fisheye that reaches its walls): the device's first
/// frame is the stream's frame 0, and differs from the open sky's.
#[test]
fn a_world_through_gige_equals_stream_frame_0() {
    require_tools();
    let fisheye = [
        "--projection",
        "equidistant",
        "--focal-length",
        "1.8",
        "--pixel-pitch",
        "20",
    ];
    let mut canyon = fisheye.to_vec();
    canyon.extend(["--canyon", "20,6,0"]);
    let (got, want) = first_block_and_stream_frame(&canyon);
    assert_eq!(
        got, want,
        "psns gige's block 1 is not psns stream's frame 0"
    );
    let (open, _) = first_block_and_stream_frame(&fisheye);
    assert_ne!(got, open, "the canyon is not in the frame");
}
