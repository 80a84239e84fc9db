//! Fuzzes the stream reader: any bytes after a valid file header must never panic, and every
//! delivered frame must carry a payload of the header's size.
#![no_main]
use libfuzzer_sys::fuzz_target;
use psns::stream::{verify, Event, FileHeader, StreamReader};
use std::io::Cursor;

fuzz_target!(|data: &[u8]| {
    // raw input as a whole stream (mostly rejected at the header)
    let _ = verify(Cursor::new(data));
    // input after a valid small header, so the frame parser is exercised
    let hd = FileHeader {
        width: 16,
        height: 8,
        ..Default::default()
    };
    let mut b = hd.encode().unwrap();
    b.extend_from_slice(data);
    if let Ok(mut rd) = StreamReader::new(Cursor::new(&b)) {
        while let Ok(Some(ev)) = rd.next_event() {
            if let Event::Frame(f) = ev {
                // after a producer restart the header (and payload size) may change
                assert_eq!(f.payload.len() as u64, rd.header().payload_size());
            }
        }
    }
});
