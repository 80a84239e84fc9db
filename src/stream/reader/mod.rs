//! Stream reader: checks every CRC, reports damage by frame id and resynchronises on the next
//! valid frame (or file header) by scanning for the magic. Works on any `Read` (no seeking), so a
//! file, a growing file, a FIFO and stdin are read the same way.

use super::{
    stride_for, CameraConstants, EndRecord, FileHeader, FrameMeta, END_MAGIC, END_RECORD_SIZE,
    FILE_HEADER_SIZE, FILE_MAGIC, FLAG_LAST, FRAME_HEADER_SIZE, FRAME_MAGIC, JSON_OFFSET,
};
use crate::error::{Error, Result};
use crate::sensor::mosaic::MosaicLayout;
use crate::sensor::packing::{payload_size_checked, unpack_into, PixelFormat};
use serde::Serialize;
use std::collections::VecDeque;
use std::fmt;
use std::io::{ErrorKind, Read};

mod extract;
mod recover;
mod verify;
pub use extract::*;
pub use recover::*;
pub use verify::*;

/// One frame record with a valid header.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Metadata from the header.
    pub meta: FrameMeta,
    /// The payload bytes (P bytes, no padding).
    pub payload: Vec<u8>,
    /// Payload CRC matched the header.
    pub payload_crc_ok: bool,
    /// Byte offset of the record in the stream.
    pub offset: u64,
}

impl Frame {
    /// Unpacks the payload into values (see [`crate::sensor::packing::unpack`]).
    pub fn codes(&self, h: &FileHeader) -> Result<Vec<u16>> {
        let mut v = Vec::new();
        self.codes_into(h, &mut v)?;
        Ok(v)
    }

    /// [`Frame::codes`] into `v`, reusing its allocation.
    pub fn codes_into(&self, h: &FileHeader, v: &mut Vec<u16>) -> Result<()> {
        unpack_into(
            &self.payload,
            h.pixel_format,
            h.bits_valid,
            h.msb_aligned,
            h.width as usize,
            h.height as usize,
            v,
        )
    }
}

/// What the reader found next.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    /// A record with a valid header (check `payload_crc_ok`).
    Frame(Frame),
    /// A damaged record (header magic or CRC wrong, or index not increasing). `index` is the
    /// header's index when plausible, else the presumed index from its neighbours; `None` when
    /// unknown (e.g. right after a producer restart).
    Corrupt {
        /// Frame index, if known.
        index: Option<u64>,
        /// Byte offset where the damage was found.
        offset: u64,
        /// What was wrong.
        reason: String,
    },
    /// Frames `from..to` (exclusive) are missing without damage in the stream (dropped).
    Gap {
        /// First missing index.
        from: u64,
        /// Index of the next frame present.
        to: u64,
    },
    /// The stream ended inside a record; the partial record is discarded.
    Truncated {
        /// Frame index, if the header was readable.
        index: Option<u64>,
        /// Byte offset of the record.
        offset: u64,
        /// Bytes present.
        have: u64,
        /// Bytes of a whole record.
        need: u64,
    },
    /// Bytes skipped while resynchronising (includes damaged records).
    Skipped {
        /// Offset of the first skipped byte.
        offset: u64,
        /// Number of bytes.
        bytes: u64,
    },
    /// A new file header where a frame was expected (producer restart); the layout may change.
    Restart(FileHeader),
    /// An end record ([`EndRecord`]): the producer stopped because of a failure.
    Aborted {
        /// Byte offset of the record.
        offset: u64,
        /// Frame records the producer says it wrote.
        frames: u64,
        /// Why it stopped.
        reason: String,
    },
}

/// Reads events from a stream. See the module docs.
pub struct StreamReader<R: Read> {
    src: R,
    buf: Vec<u8>,
    start: usize,
    /// End of the buffered bytes in `buf` (`start..end`).
    end: usize,
    offset: u64,
    eof: bool,
    header: FileHeader,
    /// Next expected index; None right after a restart.
    expected: Option<u64>,
    pending: VecDeque<Event>,
    done: bool,
    /// Byte offsets of the file headers found after the first (restarts / concatenated copies).
    restart_at: Vec<u64>,
    /// Payload buffers handed back by the consumer ([`StreamReader::recycle`]).
    spare: Vec<Vec<u8>>,
}

enum ScanEnd {
    Frame,
    Header,
    Eof,
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// Start of the error message for a first file header that is a damaged psns header (CRC
/// mismatch, or a magic one byte off / followed by a frame): the frames may still be readable in
/// degraded mode ([`StreamReader::new_recovering`]).
pub const HEADER_DAMAGED: &str = "stream file header damaged";

fn hex(b: &[u8]) -> String {
    b.iter()
        .map(|c| format!("{c:02x}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Checks the first bytes of an input: not a stream at all (`Error::Invalid`, bad input), a
/// damaged header ([`HEADER_DAMAGED`]), or the decoded header.
fn decode_first_header(a: &[u8]) -> Result<FileHeader> {
    if a.is_empty() {
        return Err(Error::Invalid("not a psns stream (empty input)".into()));
    }
    let n = a.len().min(8);
    if a[..n] != FILE_MAGIC[..n] {
        let diff = a[..n]
            .iter()
            .zip(FILE_MAGIC)
            .filter(|(x, y)| **x != *y)
            .count();
        let frame_follows = a.len() >= FILE_HEADER_SIZE + 8
            && a[FILE_HEADER_SIZE..FILE_HEADER_SIZE + 8] == FRAME_MAGIC;
        if n == 8 && (diff == 1 || frame_follows) {
            return Err(Error::HeaderDamaged(format!(
                "{HEADER_DAMAGED} (magic {}, expected {})",
                hex(&a[..8]),
                hex(&FILE_MAGIC)
            )));
        }
        return Err(Error::Invalid(format!(
            "not a psns stream (magic {}, expected {} = \\x89PSNSRAW)",
            hex(&a[..n]),
            hex(&FILE_MAGIC)
        )));
    }
    if a.len() >= FILE_HEADER_SIZE
        && super::crc32(&a[..FILE_HEADER_SIZE - 4])
            != u32::from_le_bytes(
                a[FILE_HEADER_SIZE - 4..FILE_HEADER_SIZE]
                    .try_into()
                    .expect("4"),
            )
    {
        return Err(Error::HeaderDamaged(format!(
            "{HEADER_DAMAGED} (CRC mismatch)"
        )));
    }
    FileHeader::decode(a)
}

impl<R: Read> StreamReader<R> {
    /// A reader that has read nothing yet.
    fn unread(src: R) -> Self {
        StreamReader {
            src,
            buf: Vec::new(),
            start: 0,
            end: 0,
            offset: 0,
            eof: false,
            header: FileHeader::default(),
            expected: Some(0),
            pending: VecDeque::new(),
            done: false,
            restart_at: Vec::new(),
            spare: Vec::new(),
        }
    }

    /// Hands a frame's payload buffer back for the next frame's payload: a consumer that
    /// recycles each frame's buffer reads every frame into memory already mapped instead of
    /// fresh pages (10 MB per full-size frame). At most two buffers are kept.
    pub fn recycle(&mut self, payload: Vec<u8>) {
        if self.spare.len() < 2 {
            self.spare.push(payload);
        }
    }

    /// Reads and checks the file header; fails (reading nothing more) if it is wrong.
    pub fn new(src: R) -> Result<Self> {
        let mut r = Self::unread(src);
        r.fill(FILE_HEADER_SIZE + 8)?;
        r.header = decode_first_header(r.avail())?;
        r.consume(FILE_HEADER_SIZE);
        Ok(r)
    }

    /// Degraded mode: like [`new`](Self::new), but if the file header is damaged
    /// ([`Error::HeaderDamaged`]) its geometry is inferred from the frames (the stride between two
    /// frame headers with valid CRCs, the payload length whose CRC matches a frame's payload CRC,
    /// and the header fields that still agree) or taken from `hint`; reading then starts at byte
    /// 4096 (or at the first frame header, if earlier). The header's frame count is not trusted
    /// (0). Returns how the header was replaced, `None` if it was intact. A file that is not a
    /// stream at all, or a truncated header, still fails.
    pub fn new_recovering(src: R, hint: &RecoverHint) -> Result<(Self, Option<Recovery>)> {
        let mut r = Self::unread(src);
        r.fill(FILE_HEADER_SIZE + 8)?;
        let damage = match decode_first_header(r.avail()) {
            Ok(h) => {
                r.header = h;
                r.consume(FILE_HEADER_SIZE);
                return Ok((r, None));
            }
            Err(e @ Error::HeaderDamaged(_)) => e.to_string(),
            Err(Error::Format(m)) if r.avail().len() >= FILE_HEADER_SIZE => {
                format!("{HEADER_DAMAGED} ({m})")
            }
            Err(e) => return Err(e),
        };
        // buffer until three frame headers are seen (or the end, or the cap)
        let mut want = FILE_HEADER_SIZE + (1 << 20);
        loop {
            r.fill(want)?;
            if r.eof || r.avail().len() >= RECOVER_SCAN_MAX || frames_in(r.avail(), 3).len() >= 3 {
                break;
            }
            want = (want * 2).min(RECOVER_SCAN_MAX);
        }
        let (h, start, rec) = infer_header(r.avail(), r.eof, hint, damage)?;
        r.header = h;
        r.consume(start);
        Ok((r, Some(rec)))
    }

    /// Byte offsets of the file headers met after the first one ([`Event::Restart`]): producer
    /// restarts, or streams concatenated into one file.
    pub fn restart_offsets(&self) -> &[u64] {
        &self.restart_at
    }

    /// The current file header (changes after [`Event::Restart`]).
    pub fn header(&self) -> &FileHeader {
        &self.header
    }

    fn avail(&self) -> &[u8] {
        &self.buf[self.start..self.end]
    }

    fn consume(&mut self, n: usize) {
        let n = n.min(self.end - self.start);
        self.start += n;
        self.offset += n as u64;
    }

    /// Ensures `n` bytes are buffered unless the source ends first. The buffer keeps its length
    /// (bytes `end..` are stale), so a full-size frame is not zeroed before every read. It grows
    /// with the bytes that arrive (at most doubling per read), never to a size a header merely
    /// declares: a small file whose header claims 1 GiB frames costs about twice its own size.
    fn fill(&mut self, n: usize) -> Result<()> {
        while self.end - self.start < n && !self.eof {
            if self.start > 0 {
                self.buf.copy_within(self.start..self.end, 0);
                self.end -= self.start;
                self.start = 0;
            }
            let len = self.end;
            let room = self.buf.len() - len;
            let want = (n - len).max(1 << 16).min(room.max(len).max(1 << 20));
            if self.buf.len() < len + want {
                self.buf.resize(len + want, 0);
            }
            match self.src.read(&mut self.buf[len..len + want]) {
                Ok(0) => self.eof = true,
                Ok(k) => self.end = len + k,
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => return Err(Error::io("reading stream", e)),
            }
        }
        Ok(())
    }

    /// Next event, `Ok(None)` at the end; I/O errors end the stream.
    pub fn next_event(&mut self) -> Result<Option<Event>> {
        loop {
            if let Some(e) = self.pending.pop_front() {
                return Ok(Some(e));
            }
            if self.done {
                return Ok(None);
            }
            if let Err(e) = self.step() {
                self.done = true;
                return Err(e);
            }
        }
    }

    fn stride(&self) -> usize {
        self.header.stride() as usize
    }

    fn step(&mut self) -> Result<()> {
        self.fill(8)?;
        let a = self.avail().len();
        if a == 0 {
            self.done = true;
            return Ok(());
        }
        if a < 8 {
            return self.truncated(None);
        }
        if self.avail()[..8] == FRAME_MAGIC {
            self.fill(FRAME_HEADER_SIZE)?;
            if self.avail().len() < FRAME_HEADER_SIZE {
                return self.truncated(None);
            }
            match FrameMeta::decode(self.avail()) {
                Ok((meta, pcrc)) => self.frame(meta, pcrc),
                Err(e) => self.resync(e.to_string()),
            }
        } else if self.avail()[..8] == END_MAGIC {
            self.fill(END_RECORD_SIZE)?;
            if self.avail().len() < END_RECORD_SIZE {
                return self.truncated(None);
            }
            match EndRecord::decode(self.avail()) {
                Ok(e) => {
                    self.pending.push_back(Event::Aborted {
                        offset: self.offset,
                        frames: e.frames,
                        reason: e.reason,
                    });
                    self.consume(END_RECORD_SIZE);
                    Ok(())
                }
                Err(e) => self.resync(e.to_string()),
            }
        } else if self.avail()[..8] == FILE_MAGIC {
            self.fill(FILE_HEADER_SIZE)?;
            if self.avail().len() < FILE_HEADER_SIZE {
                return self.truncated(None);
            }
            match FileHeader::decode(self.avail()) {
                Ok(h) => {
                    self.restart_at.push(self.offset);
                    self.consume(FILE_HEADER_SIZE);
                    self.header = h.clone();
                    self.expected = None;
                    self.pending.push_back(Event::Restart(h));
                    Ok(())
                }
                Err(e) => self.resync(e.to_string()),
            }
        } else {
            self.resync("frame magic missing".into())
        }
    }

    fn truncated(&mut self, index: Option<u64>) -> Result<()> {
        let have = self.avail().len();
        self.pending.push_back(Event::Truncated {
            index,
            offset: self.offset,
            have: have as u64,
            need: self.stride() as u64,
        });
        self.consume(have);
        self.done = true;
        Ok(())
    }

    fn frame(&mut self, meta: FrameMeta, pcrc: u32) -> Result<()> {
        let stride = self.stride();
        let p = self.header.payload_size() as usize;
        if let Some(e) = self.expected {
            if meta.index < e {
                // a valid header out of order (duplicate / spliced record): skip the record
                self.pending.push_back(Event::Corrupt {
                    index: Some(meta.index),
                    offset: self.offset,
                    reason: format!("index {} not after {}", meta.index, e.wrapping_sub(1)),
                });
                self.fill(stride)?;
                let n = stride.min(self.avail().len());
                self.consume(n);
                return Ok(());
            }
        }
        self.fill(stride)?;
        if self.avail().len() < stride {
            return self.truncated(Some(meta.index));
        }
        let rec = &self.avail()[..stride];
        let payload = &rec[FRAME_HEADER_SIZE..FRAME_HEADER_SIZE + p];
        let ok = super::crc32(payload) == pcrc;
        if !ok {
            // writer died mid-record and a new record follows inside this stride?
            if let Some(j) = self.valid_magic_within(FRAME_HEADER_SIZE, stride)? {
                self.pending.push_back(Event::Truncated {
                    index: Some(meta.index),
                    offset: self.offset,
                    have: j as u64,
                    need: stride as u64,
                });
                self.expected = Some(meta.index.saturating_add(1));
                self.consume(j);
                return Ok(());
            }
        }
        // a valid header inside the zero pad: the writer died in the pad and a new record follows
        let mut len = stride;
        if ok {
            if let Some(j) = self.valid_magic_within(FRAME_HEADER_SIZE + p, stride)? {
                len = j;
            }
        }
        let mut payload = self.spare.pop().unwrap_or_default();
        let rec = &self.avail()[..stride];
        payload.clear();
        payload.extend_from_slice(&rec[FRAME_HEADER_SIZE..FRAME_HEADER_SIZE + p]);
        if let Some(e) = self.expected {
            if meta.index > e {
                self.pending.push_back(Event::Gap {
                    from: e,
                    to: meta.index,
                });
            }
        }
        self.pending.push_back(Event::Frame(Frame {
            meta,
            payload,
            payload_crc_ok: ok,
            offset: self.offset,
        }));
        self.expected = Some(meta.index.saturating_add(1));
        self.consume(len);
        Ok(())
    }

    /// Offset (in `lo..hi` of the buffered record) of a magic with a valid header, if any.
    fn valid_magic_within(&mut self, lo: usize, hi: usize) -> Result<Option<usize>> {
        let mut from = lo;
        while from < hi {
            let Some(i) = find(&self.avail()[from..hi], b"\x89PSNS") else {
                return Ok(None);
            };
            let j = from + i;
            if self.valid_at(j)? {
                return Ok(Some(j));
            }
            from = j + 1;
        }
        Ok(None)
    }

    /// True if a frame header, file header or end record with a valid CRC starts at `j` of the
    /// buffer.
    fn valid_at(&mut self, j: usize) -> Result<bool> {
        self.fill(j + 8)?;
        let a = self.avail();
        if a.len() < j + 8 {
            return Ok(false);
        }
        if a[j..j + 8] == END_MAGIC {
            self.fill(j + END_RECORD_SIZE)?;
            let a = self.avail();
            Ok(a.len() >= j + END_RECORD_SIZE && EndRecord::decode(&a[j..]).is_ok())
        } else if a[j..j + 8] == FRAME_MAGIC {
            self.fill(j + FRAME_HEADER_SIZE)?;
            let a = self.avail();
            Ok(a.len() >= j + FRAME_HEADER_SIZE && FrameMeta::decode(&a[j..]).is_ok())
        } else if a[j..j + 8] == FILE_MAGIC {
            self.fill(j + FILE_HEADER_SIZE)?;
            let a = self.avail();
            Ok(a.len() >= j + FILE_HEADER_SIZE && FileHeader::decode(&a[j..]).is_ok())
        } else {
            Ok(false)
        }
    }

    /// Damage at the current position: scan for the next valid header, then report.
    fn resync(&mut self, reason: String) -> Result<()> {
        let p0 = self.offset;
        let stride = self.stride() as u64;
        // index fields of damaged records whose frame magic survived
        let mut cands: Vec<Option<u64>> = Vec::new();
        let note = |a: &[u8], c: &mut Vec<Option<u64>>| {
            if a.len() >= 8 && a[..8] == FRAME_MAGIC {
                c.push(if a.len() >= 16 {
                    Some(u64::from_le_bytes(a[8..16].try_into().expect("8 bytes")))
                } else {
                    None
                });
            }
        };
        note(self.avail(), &mut cands);
        self.consume(1);
        let end = loop {
            self.fill(FILE_HEADER_SIZE)?;
            let a = self.avail();
            if a.is_empty() {
                break ScanEnd::Eof;
            }
            match find(a, b"\x89PSNS") {
                None => {
                    let keep = if self.eof { 0 } else { 4.min(a.len()) };
                    let n = a.len() - keep;
                    self.consume(n);
                    if self.eof {
                        break ScanEnd::Eof;
                    }
                }
                Some(i) => {
                    self.consume(i);
                    if self.valid_at(0)? {
                        break if self.avail()[..8] == FRAME_MAGIC {
                            ScanEnd::Frame
                        } else {
                            ScanEnd::Header
                        };
                    }
                    note(self.avail(), &mut cands);
                    self.consume(1);
                }
            }
        };
        let skipped = self.offset - p0;
        let next_index = match end {
            ScanEnd::Frame => FrameMeta::decode(self.avail()).ok().map(|(m, _)| m.index),
            _ => None,
        };
        let rounded = (skipped + stride / 2) / stride;
        let (lo, hi) = match (self.expected, next_index) {
            (Some(e), Some(k)) if k >= e => (Some(e), Some(k)),
            (Some(e), _) => (Some(e), None),
            _ => (None, None),
        };
        // number of damaged records
        let mut n_damaged = (cands.len() as u64).max(rounded);
        if let (Some(e), Some(k)) = (lo, hi) {
            n_damaged = n_damaged.min(k - e);
        }
        // ids: plausible header indexes first, then the lowest unassigned expected ones
        let mut ids = std::collections::BTreeSet::new();
        if let Some(e) = lo {
            for c in cands.iter().flatten() {
                if *c >= e && hi.is_none_or(|k| *c < k) && (ids.len() as u64) < n_damaged {
                    ids.insert(*c);
                }
            }
            let mut i = e;
            while (ids.len() as u64) < n_damaged && hi.is_none_or(|k| i < k) {
                ids.insert(i);
                i += 1;
            }
        }
        let ids: Vec<u64> = ids.into_iter().collect();
        let n_reports = if lo.is_some() {
            ids.len() as u64
        } else {
            n_damaged
        };
        for k in 0..n_reports {
            self.pending.push_back(Event::Corrupt {
                index: ids.get(k as usize).copied(),
                offset: p0 + k * stride,
                reason: reason.clone(),
            });
        }
        if let (Some(e), Some(k)) = (lo, hi) {
            // what remains of e..k was dropped upstream: the complement of ids
            let mut from = e;
            for &i in ids.iter().chain(std::iter::once(&k)) {
                if i > from {
                    self.pending.push_back(Event::Gap { from, to: i });
                }
                from = i.saturating_add(1);
            }
            // the frame itself then must not report the gap again
            self.expected = Some(k);
        } else if let (Some(e), Some(&last)) = (lo, ids.last()) {
            self.expected = Some(last.max(e).saturating_add(1));
        }
        if skipped > 0 {
            self.pending.push_back(Event::Skipped {
                offset: p0,
                bytes: skipped,
            });
        }
        if let ScanEnd::Eof = end {
            self.done = true;
        }
        Ok(())
    }
}

impl<R: Read> Iterator for StreamReader<R> {
    type Item = Result<Event>;
    fn next(&mut self) -> Option<Result<Event>> {
        self.next_event().transpose()
    }
}
