//! Stream format: write → read round trips, corruption handling, FIFOs, property tests.

use proptest::prelude::*;
use psns::sensor::packing::PixelFormat;
use psns::stream::*;
use std::io::Cursor;

fn header(fmt: PixelFormat, w: u32, h: u32) -> FileHeader {
    FileHeader {
        width: w,
        height: h,
        pixel_format: fmt,
        bits_valid: if fmt == PixelFormat::Mono8 { 8 } else { 12 },
        seed: 7,
        producer: "psns test".into(),
        json: r#"{"test":true}"#.into(),
        ..Default::default()
    }
}

fn meta(i: u64) -> FrameMeta {
    FrameMeta {
        index: i,
        flags: FLAG_SATURATION,
        exposure_start_ns: 1_700_000_000_000_000_000 + i as i64 * 50_000_000,
        exposure_end_ns: 1_700_000_000_001_000_000 + i as i64 * 50_000_000,
        exposure_us: 1000.0,
        gain_db: 3.5,
        black_level: 16.0,
        temperature_c: 25.0,
        sun_azimuth_deg: 180.0 + i as f64,
        sun_elevation_deg: 40.0,
        sun_camera: [0.1, -0.2, 0.97],
        attitude_wxyz: [1.0, 0.0, 0.0, 0.0],
        lat_deg: 48.1,
        lon_deg: 11.6,
        height_m: 520.0,
        saturated: [i as u32, 1, 2, 3],
        turbidity: 2.5,
        albedo: 0.2,
        ..Default::default()
    }
}

fn codes(i: u64, n: usize, bits: u8) -> Vec<u16> {
    (0..n)
        .map(|k| ((k as u64 * 2_654_435_761 + i * 97) % (1u64 << bits)) as u16)
        .collect()
}

/// A stream of `n` frames in memory.
fn make(fmt: PixelFormat, w: u32, h: u32, n: u64) -> (Vec<u8>, Vec<Vec<u16>>) {
    let hd = header(fmt, w, h);
    let mut wr = StreamWriter::new(Vec::new(), &hd).unwrap();
    let mut all = Vec::new();
    for i in 0..n {
        let c = codes(i, (w * h) as usize, 12);
        wr.write_frame(&meta(i), &c).unwrap();
        all.push(c);
    }
    (wr.finish().unwrap(), all)
}

fn events(bytes: &[u8]) -> Vec<Event> {
    StreamReader::new(Cursor::new(bytes))
        .unwrap()
        .map(|e| e.unwrap())
        .collect()
}

#[test]
fn round_trip_every_format() {
    for fmt in PixelFormat::ALL {
        let (bytes, all) = make(fmt, 16, 8, 3);
        let hd = header(fmt, 16, 8);
        assert_eq!(bytes.len() as u64, 4096 + 3 * hd.stride(), "{fmt}");
        let mut rd = StreamReader::new(Cursor::new(&bytes)).unwrap();
        assert_eq!(rd.header(), &hd);
        let mut n = 0;
        while let Some(ev) = rd.next_event().unwrap() {
            let Event::Frame(fr) = ev else {
                panic!("{fmt}: unexpected {ev:?}")
            };
            assert!(fr.payload_crc_ok);
            let mut m = meta(n);
            m.flags = fr.meta.flags;
            assert_eq!(fr.meta, m);
            let back = fr.codes(&hd).unwrap();
            let want: Vec<u16> = if fmt == PixelFormat::Mono8 {
                all[n as usize].iter().map(|c| c >> 4).collect()
            } else {
                all[n as usize].clone()
            };
            assert_eq!(back, want, "{fmt} frame {n}");
            // re-encoding the decoded frame gives the same bytes
            let off = hd.frame_offset(n) as usize;
            assert_eq!(
                &bytes[off..off + 256],
                &fr.meta.encode(crc32(&fr.payload))[..]
            );
            n += 1;
        }
        assert_eq!(n, 3);
        let rep = verify(Cursor::new(&bytes)).unwrap();
        assert!(rep.intact(), "{rep}");
        assert_eq!(rep.frames, 3);
    }
}

#[test]
fn mono8_at_8_bit_depth_stores_the_value() {
    let hd = header(PixelFormat::Mono8, 4, 2);
    let mut wr = StreamWriter::new(Vec::new(), &hd)
        .unwrap()
        .with_sensor_bits(8);
    let c: Vec<u16> = vec![0, 1, 2, 200, 255, 17, 33, 128];
    wr.write_frame(&meta(0), &c).unwrap();
    let b = wr.finish().unwrap();
    assert_eq!(
        &b[4096 + 256..4096 + 264],
        &[0, 1, 2, 200, 255, 17, 33, 128]
    );
}

#[test]
fn same_input_same_bytes_and_file_patch() {
    let (a, _) = make(PixelFormat::Mono12p, 16, 8, 4);
    let (b, _) = make(PixelFormat::Mono12p, 16, 8, 4);
    assert_eq!(a, b);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("s.psns");
    let hd = header(PixelFormat::Mono12p, 16, 8);
    let mut w = FileStreamWriter::create(&p, &hd).unwrap();
    for i in 0..4 {
        w.write_frame(&meta(i), &codes(i, 128, 12)).unwrap();
    }
    assert_eq!(w.finish().unwrap(), 4);
    let f = std::fs::read(&p).unwrap();
    assert_eq!(f.len(), a.len());
    // only the frame count and the header CRC differ
    let diff: Vec<usize> = (0..f.len()).filter(|&i| f[i] != a[i]).collect();
    assert!(
        diff.iter()
            .all(|&i| (64..72).contains(&i) || (4092..4096).contains(&i)),
        "{diff:?}"
    );
    assert_eq!(FileHeader::decode(&f).unwrap().frame_count, 4);
    assert!(verify(Cursor::new(&f)).unwrap().clean());
}

#[test]
fn bit_flips_in_headers_and_payloads() {
    let (bytes, _) = make(PixelFormat::Mono16, 16, 8, 5);
    let stride = header(PixelFormat::Mono16, 16, 8).stride() as usize;
    // flip one bit at many positions inside frame 2; frames 0,1,3,4 must survive
    for pos in [0usize, 7, 8, 15, 20, 100, 251, 253, 256, 300, 256 + 255] {
        for bit in [0u8, 7] {
            let mut b = bytes.clone();
            b[4096 + 2 * stride + pos] ^= 1 << bit;
            let rep = verify(Cursor::new(&b)).unwrap();
            assert!(!rep.clean(), "pos {pos}");
            assert_eq!(rep.frames, 4, "pos {pos}: {rep}");
            assert_eq!(rep.corrupt.len(), 1, "pos {pos}: {rep}");
            assert_eq!(rep.corrupt[0].index, Some(2), "pos {pos}: {rep}");
            assert_eq!(rep.dropped, 0, "pos {pos}: {rep}");
            let idx: Vec<u64> = events(&b)
                .into_iter()
                .filter_map(|e| match e {
                    Event::Frame(f) if f.payload_crc_ok => Some(f.meta.index),
                    _ => None,
                })
                .collect();
            assert_eq!(idx, [0, 1, 3, 4]);
        }
    }
    // a flip in the pad is not an error (the pad is not covered)
    let mut b = bytes.clone();
    b[4096 + 2 * stride + 256 + 256 + 10] ^= 1;
    assert!(verify(Cursor::new(&b)).unwrap().intact());
    // file header damage: error, nothing read
    let mut b = bytes.clone();
    b[30] ^= 1;
    assert!(StreamReader::new(Cursor::new(&b)).is_err());
    let mut b = bytes.clone();
    b[8] = 2; // major 2
    assert!(StreamReader::new(Cursor::new(&b)).is_err());
}

#[test]
fn two_adjacent_damaged_frames() {
    let (bytes, _) = make(PixelFormat::Mono8, 16, 8, 6);
    let stride = 4096usize;
    let mut b = bytes.clone();
    b[4096 + 2 * stride + 9] ^= 4; // header of 2 (index field)
    b[4096 + 3 * stride] ^= 1; // magic of 3
    let rep = verify(Cursor::new(&b)).unwrap();
    let ids: Vec<_> = rep.corrupt.iter().map(|d| d.index).collect();
    assert_eq!(ids, [Some(2), Some(3)], "{rep}");
    assert_eq!(rep.frames, 4);
    assert_eq!(rep.dropped, 0);
}

#[test]
fn truncation_at_every_offset_of_last_record() {
    let (bytes, _) = make(PixelFormat::Mono12Packed, 16, 8, 3);
    let stride = 4096usize;
    let start = 4096 + 2 * stride;
    // the same bytes with the frame count in the header: a finished stream, cut later
    let mut counted = bytes.clone();
    let mut h = FileHeader::decode(&counted).unwrap();
    h.frame_count = 3;
    counted[..4096].copy_from_slice(&h.encode().unwrap());
    for cut in start + 1..bytes.len() {
        // count 0: the producer was cut off while writing the record (unfinished, not damaged)
        let rep = verify(Cursor::new(&bytes[..cut])).unwrap();
        assert_eq!(rep.frames, 2, "cut {cut}");
        assert!(rep.truncated.is_empty(), "cut {cut}: {rep}");
        let tail = rep.cut_short.as_ref().expect("the cut-short record");
        if cut - start >= 256 {
            assert_eq!(tail.index, Some(2));
        }
        assert!(rep.corrupt.is_empty(), "cut {cut}: {rep}");
        assert_eq!(rep.status, VerifyStatus::Unfinished, "cut {cut}: {rep}");
        // counted: damaged
        let rep = verify(Cursor::new(&counted[..cut])).unwrap();
        assert_eq!(rep.truncated.len(), 1, "cut {cut}: {rep}");
        assert!(rep.cut_short.is_none() && !rep.clean(), "cut {cut}: {rep}");
        assert_eq!(rep.status, VerifyStatus::Damaged, "cut {cut}: {rep}");
    }
    // cut exactly at a record boundary: clean but shorter
    let rep = verify(Cursor::new(&bytes[..start])).unwrap();
    assert!(rep.intact());
    assert_eq!(rep.frames, 2);
}

#[test]
fn frame_count_mismatch_reports_truncated_file() {
    let (bytes, _) = make(PixelFormat::Mono16, 16, 8, 3);
    let mut hd = header(PixelFormat::Mono16, 16, 8);
    hd.frame_count = 3;
    let mut b = bytes.clone();
    b[..4096].copy_from_slice(&hd.encode().unwrap());
    assert!(verify(Cursor::new(&b)).unwrap().clean());
    let cut = 4096 + 2 * hd.stride() as usize;
    let rep = verify(Cursor::new(&b[..cut])).unwrap();
    assert_eq!(rep.count_mismatch, Some((3, 2)));
    assert!(!rep.clean());
}

#[test]
fn garbage_between_frames_and_restart_and_gap() {
    let (bytes, _) = make(PixelFormat::Mono12p, 16, 8, 4);
    let stride = 4096usize;
    let rec = |i: usize| &bytes[4096 + i * stride..4096 + (i + 1) * stride];
    for glen in [1usize, 5, 300, 4095, 4096, 9000] {
        let mut b = bytes[..4096].to_vec();
        b.extend_from_slice(rec(0));
        b.extend_from_slice(rec(1));
        b.extend((0..glen).map(|k| (k * 31 + 7) as u8));
        b.extend_from_slice(rec(2));
        b.extend_from_slice(rec(3));
        let rep = verify(Cursor::new(&b)).unwrap();
        assert_eq!(rep.frames, 4, "glen {glen}: {rep}");
        assert_eq!(rep.skipped_bytes, glen as u64);
        assert_eq!(rep.dropped, 0);
        assert!(rep.corrupt.is_empty(), "glen {glen}: {rep}");
    }
    // producer dropped frame 2: gap reported, flag set by the writer
    let hd = header(PixelFormat::Mono12p, 16, 8);
    let mut wr = StreamWriter::new(Vec::new(), &hd).unwrap();
    for i in [0u64, 1, 3] {
        wr.write_frame(&meta(i), &codes(i, 128, 12)).unwrap();
    }
    let b = wr.finish().unwrap();
    let ev = events(&b);
    assert!(ev.contains(&Event::Gap { from: 2, to: 3 }));
    let Some(Event::Frame(f)) = ev.last() else {
        panic!()
    };
    assert_ne!(f.meta.flags & FLAG_DROPPED, 0);
    let rep = verify(Cursor::new(&b)).unwrap();
    assert_eq!(rep.dropped, 1);
    // restart: a killed producer (partial record) followed by a new file header
    for (cut, want) in [
        (300usize, vec!["frame", "trunc", "restart", "frame"]),
        (1000, vec!["frame", "frame", "restart", "frame"]),
        // a partial frame header cannot be told from a damaged one: corrupt + skipped
        (100, vec!["frame", "other", "other", "restart", "frame"]),
    ] {
        let mut b = bytes[..4096 + stride + cut].to_vec();
        let hd2 = header(PixelFormat::Mono16, 8, 4);
        let mut wr = StreamWriter::new(Vec::new(), &hd2).unwrap();
        wr.write_frame(&meta(0), &codes(0, 32, 12)).unwrap();
        b.extend_from_slice(&wr.finish().unwrap());
        let ev = events(&b);
        let kinds: Vec<&str> = ev
            .iter()
            .map(|e| match e {
                Event::Frame(_) => "frame",
                Event::Truncated { .. } => "trunc",
                Event::Restart(_) => "restart",
                _ => "other",
            })
            .collect();
        assert_eq!(kinds, want, "cut {cut}: {ev:?}");
        let Some(Event::Frame(f)) = ev.last() else {
            panic!()
        };
        assert_eq!(f.payload.len(), 64);
        assert!(f.payload_crc_ok);
    }
}

#[test]
fn extract_returns_codes_and_meta() {
    let (bytes, all) = make(PixelFormat::Mono12p, 16, 8, 3);
    let x = extract_frame(Cursor::new(&bytes), 1).unwrap();
    assert_eq!(x.codes, all[1]);
    assert_eq!(x.meta.index, 1);
    let j = serde_json::to_string(&x).unwrap();
    assert!(j.contains("\"sun_azimuth_deg\":181.0"), "{j}");
    assert!(extract_frame(Cursor::new(&bytes), 5).is_err());
}

#[cfg(unix)]
mod fifo {
    use super::*;
    use std::io::Read;
    use std::time::Duration;

    fn mkfifo(p: &std::path::Path) {
        let st = std::process::Command::new("mkfifo")
            .arg(p)
            .status()
            .unwrap();
        assert!(st.success());
    }

    #[test]
    fn fifo_slow_reader_gets_identical_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("fifo");
        mkfifo(&p);
        let (want, _) = make(PixelFormat::Mono16, 64, 32, 6);
        let p2 = p.clone();
        let writer = std::thread::spawn(move || {
            let hd = header(PixelFormat::Mono16, 64, 32);
            let mut w = FileStreamWriter::create(&p2, &hd).unwrap();
            for i in 0..6 {
                w.write_frame(&meta(i), &codes(i, 64 * 32, 12)).unwrap();
            }
            w.finish().unwrap()
        });
        let reader = std::thread::spawn(move || {
            let f = std::fs::File::open(&p).unwrap();
            let mut rd = StreamReader::new(f).unwrap();
            let mut frames = 0;
            while let Some(ev) = rd.next_event().unwrap() {
                assert!(
                    matches!(ev, Event::Frame(ref f) if f.payload_crc_ok),
                    "{ev:?}"
                );
                frames += 1;
                std::thread::sleep(Duration::from_millis(30));
            }
            frames
        });
        assert_eq!(writer.join().unwrap(), 6);
        assert_eq!(reader.join().unwrap(), 6);
        // the bytes through a FIFO equal the in-memory bytes (frame count stays 0 on a FIFO)
        let p = dir.path().join("fifo");
        let want2 = want.clone();
        let p3 = p.clone();
        let w = std::thread::spawn(move || {
            let hd = header(PixelFormat::Mono16, 64, 32);
            let mut w = FileStreamWriter::create(&p3, &hd).unwrap();
            for i in 0..6 {
                w.write_frame(&meta(i), &codes(i, 64 * 32, 12)).unwrap();
            }
            w.finish().unwrap();
        });
        let mut got = Vec::new();
        std::fs::File::open(&p)
            .unwrap()
            .read_to_end(&mut got)
            .unwrap();
        w.join().unwrap();
        assert_eq!(got, want2);
    }

    #[test]
    fn fifo_reader_quits_early_gives_broken_pipe() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("fifo");
        mkfifo(&p);
        let p2 = p.clone();
        let writer = std::thread::spawn(move || {
            let hd = header(PixelFormat::Mono16, 64, 32);
            let mut w = FileStreamWriter::create(&p2, &hd).unwrap();
            for i in 0..10_000 {
                if let Err(e) = w.write_frame(&meta(i), &codes(i, 64 * 32, 12)) {
                    return Some(e);
                }
            }
            None
        });
        {
            let f = std::fs::File::open(&p).unwrap();
            let mut rd = StreamReader::new(f).unwrap();
            for _ in 0..2 {
                assert!(matches!(rd.next_event().unwrap(), Some(Event::Frame(_))));
            }
        } // reader closes
        let e = writer.join().unwrap().expect("writer must fail");
        assert!(e.is_broken_pipe(), "{e}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn random_header_fields_round_trip(
        index in any::<u64>(), flags in any::<u32>(), t0 in any::<i64>(), t1 in any::<i64>(),
        f in proptest::collection::vec(any::<f64>(), 16), sat in any::<[u32; 4]>(),
        turb in any::<f32>(), alb in any::<f32>(), w in 1u32..40, h in 1u32..12,
        fmt in 0usize..4, seed in any::<u64>(), bits in 1u8..=12, cls in any::<[f32; 6]>(),
    ) {
        let fmt = PixelFormat::ALL[fmt];
        let m = FrameMeta {
            index, flags, exposure_start_ns: t0, exposure_end_ns: t1, host_time_ns: t0 ^ t1,
            exposure_us: f[0], gain_db: f[1], black_level: f[2], temperature_c: f[3],
            sun_azimuth_deg: f[4], sun_elevation_deg: f[5], sun_camera: [f[6], f[7], f[8]],
            attitude_wxyz: [f[9], f[10], f[11], f[12]], lat_deg: f[13], lon_deg: f[14],
            height_m: f[15], saturated: sat, turbidity: turb, albedo: alb, class_fractions: cls,
        };
        let b = m.encode(0x1234_5678);
        let (m2, c) = FrameMeta::decode(&b).unwrap();
        prop_assert_eq!(c, 0x1234_5678);
        // compare bitwise (NaN-safe)
        prop_assert_eq!(m2.encode(c), b);
        let hd = FileHeader {
            width: w, height: h, pixel_format: fmt, seed,
            bits_valid: if fmt == PixelFormat::Mono8 { 8 } else { bits },
            ..Default::default()
        };
        let hb = hd.encode().unwrap();
        prop_assert_eq!(FileHeader::decode(&hb).unwrap().encode().unwrap(), hb.clone());
        // a whole one-frame stream reads back
        let mut wr = StreamWriter::new(Vec::new(), &hd).unwrap().with_sensor_bits(8);
        let n = (w * h) as usize;
        let maxv = if fmt == PixelFormat::Mono8 { 255 } else { (1u32 << bits) - 1 };
        let cs: Vec<u16> = (0..n).map(|k| (k as u32 * 7919 % (maxv + 1)) as u16).collect();
        let mut m0 = m;
        m0.index = 0;
        wr.write_frame(&m0, &cs).unwrap();
        let s = wr.finish().unwrap();
        let x = extract_frame(Cursor::new(&s), 0).unwrap();
        prop_assert_eq!(x.codes, cs);
    }

    #[test]
    fn random_damage_never_panics_and_keeps_intact_frames(
        flips in proptest::collection::vec((0usize..4096 * 6, any::<u8>()), 0..6),
        cut in 4096usize..4096 * 7,
    ) {
        let (mut b, _) = make(PixelFormat::Mono8, 16, 8, 6);
        let mut hit = std::collections::BTreeSet::new();
        for (pos, x) in &flips {
            if *x != 0 {
                b[4096 + pos] ^= x;
                hit.insert((pos / 4096) as u64);
            }
        }
        let cut = cut.min(b.len());
        let rep = verify(Cursor::new(&b[..cut])).unwrap();
        let whole = ((cut - 4096) / 4096) as u64;
        // every undamaged whole record is delivered
        let intact = (0..whole).filter(|i| !hit.contains(i)).count() as u64;
        prop_assert!(rep.frames >= intact && rep.frames <= whole, "intact {} whole {}: {}", intact, whole, rep);
        let _ = events(&b[..cut]);
    }
}
