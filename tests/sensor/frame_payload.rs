//! `RawPipeline::render` with a payload asked for: the stream payload and its CRC-32 that come with a frame
//! (the fast path's Mono16 CRC taken band by band, packed formats' CRC chunk by chunk) are the
//! frame's codes packed as `packing::pack` packs them and the CRC of those bytes, on the fast
//! path, the exact path and a PSNS preset (whose Mono16 CRC is left to the writer).

use psns::camera::{Attitude, Intrinsics};
use psns::config::SceneConfig;
use psns::pipeline::{FrameRequest, RawPipeline};
use psns::sensor::packing::{self, PixelFormat};
use psns::sensor::Preset;
use psns::sun::SunPosition;

/// The fast path, the exact path and a PSNS preset: (exact, preset).
const PATHS: [(bool, Preset); 3] = [
    (false, Preset::Camera),
    (true, Preset::Camera),
    (false, Preset::Gniipi),
];

/// A 152 x 36 frame with the full sensor's field of view; 36 rows: two full 16-row bands and a
/// short one.
fn small_pipeline(exact: bool, preset: Preset) -> RawPipeline {
    let mut cfg = SceneConfig::default();
    cfg.raw.preset = preset;
    cfg.camera.intrinsics = Intrinsics {
        pixel_pitch_um: 3.45 * 16.0,
        ..Intrinsics::with_size(152, 36)
    };
    cfg.raw.exact = exact;
    RawPipeline::new(&cfg).unwrap()
}

#[test]
fn payload_and_crc_match_the_codes() {
    for (exact, preset) in PATHS {
        let pipe = small_pipeline(exact, preset);
        let sun = SunPosition::new(40.0, 120.0);
        let att = Attitude::enu(30.0, 50.0, 0.0);
        let want = pipe.render(FrameRequest::sky(3, sun, att)).unwrap().frame;
        for fmt in [
            PixelFormat::Mono8,
            PixelFormat::Mono12p,
            PixelFormat::Mono12Packed,
            PixelFormat::Mono16,
        ] {
            let req = FrameRequest::sky(3, sun, att).with_payload(fmt, Vec::new());
            let r = pipe.render(req).unwrap();
            let (f, crc, bytes) = (r.frame, r.payload_crc, r.bytes);
            assert_eq!(
                f.codes.data, want.codes.data,
                "exact {exact} {preset:?} {fmt}"
            );
            let mut packed = Vec::new();
            packing::pack(&f.codes.data, f.bit_depth, fmt, false, &mut packed).unwrap();
            let payload: &[u8] = if packing::codes_are_payload(fmt) {
                // the codes are the payload; `bytes` is left alone
                assert!(bytes.is_empty());
                bytemuck::cast_slice(&f.codes.data)
            } else {
                &bytes
            };
            assert_eq!(payload, &packed[..], "exact {exact} {preset:?} {fmt}");
            // the camera's fast path takes the Mono16 CRC from its bands; other paths leave it to
            // the writer; packed formats have theirs from packing
            let banded = !exact && preset == Preset::Camera;
            let want = if packing::codes_are_payload(fmt) && !banded {
                None
            } else {
                Some(crc32fast::hash(&packed))
            };
            assert_eq!(crc, want, "exact {exact} {preset:?} {fmt}");
            assert_eq!(
                f.codes_crc32.is_some(),
                banded && packing::codes_are_payload(fmt),
                "exact {exact} {preset:?} {fmt}"
            );
        }
    }
}

#[test]
fn frame_after_a_lead_keeps_the_lead_and_makes_the_same_codes() {
    for (exact, preset) in PATHS {
        let pipe = small_pipeline(exact, preset);
        let sun = SunPosition::new(40.0, 120.0);
        let att = Attitude::enu(30.0, 50.0, 0.0);
        let want = pipe.render(FrameRequest::sky(3, sun, att)).unwrap().frame;
        let n = want.codes.data.len();
        // a fresh buffer shorter than the lead, then a reused one holding stale codes
        let mut buf = vec![7u16, 8];
        for lead in [32usize, 32, 0, 5] {
            let req = FrameRequest::sky(3, sun, att).into_codes(buf, lead);
            let f = pipe.render(req).unwrap().frame;
            let b = if lead == 0 {
                // no lead: the codes are the frame's, in the buffer given
                assert!(f.lead_buffer.is_none());
                f.codes.data.clone()
            } else {
                assert_eq!((f.codes.width, f.codes.height), (0, 0));
                f.lead_buffer.expect("the buffer comes back")
            };
            assert_eq!(b.len(), lead + n, "exact {exact} {preset:?} lead {lead}");
            assert_eq!(&b[lead..], &want.codes.data[..], "exact {exact} {preset:?}");
            if lead >= 2 {
                assert_eq!(&b[..2], &[7, 8], "the lead is kept");
            }
            assert_eq!(f.saturated, want.saturated);
            buf = b;
            buf[..2].copy_from_slice(&[7, 8]);
        }
    }
}
