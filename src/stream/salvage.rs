//! The intact frames of a stream that did not end whole (a producer killed by `kill -9` or a full
//! disk, or one that marked its stream aborted), as a finished stream has them: what
//! `psns recover` writes.

use super::reader::{Event, Frame, StreamReader};
use super::{FileHeader, FLAG_LAST};
use crate::error::Result;
use std::io::Read;

/// Reads a stream and hands out its intact frames in order, the last one flagged
/// [`FLAG_LAST`]; everything else is left out and noted.
///
/// Intact: a frame record whose header and payload CRCs hold. Left out: damaged records, a
/// record cut short, an end record (its reason is noted), and a second stream in the input
/// (reading stops at its file header, since its frame indexes may start again).
pub struct Salvage<R: Read> {
    rd: StreamReader<R>,
    /// The intact frame read ahead, handed out once the next one (or the end) is known.
    held: Option<Frame>,
    done: bool,
    notes: Vec<String>,
    frames: u64,
}

impl<R: Read> Salvage<R> {
    /// Starts on a reader that has read the file header.
    pub fn new(rd: StreamReader<R>) -> Self {
        Salvage {
            rd,
            held: None,
            done: false,
            notes: Vec::new(),
            frames: 0,
        }
    }

    /// The file header of the finished stream: the input's, with the frame count unknown (0,
    /// for the writer to set) and no aborted mark.
    pub fn header(&self) -> FileHeader {
        FileHeader {
            frame_count: 0,
            aborted: false,
            ..self.rd.header().clone()
        }
    }

    /// What was left out or found, one line each, so far.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// Intact frames handed out so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Hands a frame's payload buffer back for the next frame.
    pub fn recycle(&mut self, payload: Vec<u8>) {
        self.rd.recycle(payload);
    }

    /// The next intact frame (the last flagged [`FLAG_LAST`]), `None` at the end.
    pub fn next_frame(&mut self) -> Result<Option<Frame>> {
        while !self.done {
            let Some(ev) = self.rd.next_event()? else {
                self.done = true;
                break;
            };
            let note = match ev {
                Event::Frame(f) if f.payload_crc_ok => {
                    if let Some(prev) = self.held.replace(f) {
                        self.frames += 1;
                        return Ok(Some(prev));
                    }
                    continue;
                }
                Event::Frame(f) => format!(
                    "frame {} at byte {}: payload CRC mismatch",
                    f.meta.index, f.offset
                ),
                Event::Corrupt {
                    index,
                    offset,
                    reason,
                } => format!("{} at byte {offset}: {reason}", frame_name(index)),
                Event::Truncated {
                    index,
                    offset,
                    have,
                    need,
                } => format!(
                    "{} at byte {offset}: cut short ({have} of {need} bytes)",
                    frame_name(index)
                ),
                Event::Gap { from, to } => format!(
                    "frames {from}..{} are not in the stream (dropped by its producer)",
                    to - 1
                ),
                Event::Skipped { .. } => continue,
                Event::Aborted { reason, .. } => {
                    format!("the stream was aborted by its producer: {reason}")
                }
                Event::Restart(_) => {
                    self.done = true;
                    let at = self.rd.restart_offsets().last().copied().unwrap_or(0);
                    format!("another stream starts at byte {at}: it and what follows are left out")
                }
            };
            self.notes.push(note);
        }
        Ok(self.held.take().map(|mut f| {
            f.meta.flags |= FLAG_LAST;
            self.frames += 1;
            f
        }))
    }
}

fn frame_name(index: Option<u64>) -> String {
    index.map_or_else(|| "a record".to_string(), |i| format!("frame {i}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stream::{FrameMeta, StreamWriter, FLAG_DROPPED};

    fn stream(n: u64) -> Vec<u8> {
        let h = FileHeader {
            width: 8,
            height: 4,
            ..Default::default()
        };
        let mut w = StreamWriter::new(Vec::new(), &h).unwrap();
        for i in 0..n {
            let m = FrameMeta {
                index: i,
                ..Default::default()
            };
            w.write_frame(&m, &[i as u16; 32]).unwrap();
        }
        w.finish().unwrap()
    }

    fn salvage(b: &[u8]) -> (Vec<FrameMeta>, Vec<String>) {
        let mut s = Salvage::new(StreamReader::new(b).unwrap());
        let mut v = Vec::new();
        while let Some(f) = s.next_frame().unwrap() {
            v.push(f.meta);
        }
        assert_eq!(s.frames(), v.len() as u64);
        (v, s.notes().to_vec())
    }

    #[test]
    fn a_cut_off_stream_gives_its_whole_frames_the_last_flagged() {
        let b = stream(4);
        let stride = (b.len() - 4096) / 4;
        // killed while writing frame 3: its record cut short
        let (m, notes) = salvage(&b[..4096 + 3 * stride + 300]);
        assert_eq!(m.iter().map(|m| m.index).collect::<Vec<_>>(), [0, 1, 2]);
        assert_eq!(
            m.iter().map(|m| m.flags).collect::<Vec<_>>(),
            [0, 0, FLAG_LAST]
        );
        assert!(
            notes[0].contains("frame 3") && notes[0].contains("cut short"),
            "{notes:?}"
        );
        // a damaged frame in the middle is left out and named
        let mut d = b.clone();
        d[4096 + stride + 300] ^= 1;
        let (m, notes) = salvage(&d);
        assert_eq!(m.iter().map(|m| m.index).collect::<Vec<_>>(), [0, 2, 3]);
        assert_eq!(m[2].flags & FLAG_LAST, FLAG_LAST);
        assert_eq!(m[1].flags & FLAG_DROPPED, 0, "the reader's flags, as read");
        assert!(notes[0].starts_with("frame 1 at byte"), "{notes:?}");
        // nothing intact: nothing handed out
        let (m, _) = salvage(&b[..4096 + 10]);
        assert!(m.is_empty());
    }
}
