//! Stream reader: checks every CRC, reports damage by frame id and resynchronises on the next
//! valid frame (or file header) by scanning for the magic. Works on any `Read` (no seeking), so a
//! file, a growing file, a FIFO and stdin are read the same way.

use super::{FileHeader, FrameMeta, FILE_HEADER_SIZE, FILE_MAGIC, FRAME_HEADER_SIZE, FRAME_MAGIC};
use crate::error::{Error, Result};
use crate::sensor::packing::unpack;
use serde::Serialize;
use std::collections::VecDeque;
use std::fmt;
use std::io::{ErrorKind, Read};

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
    /// Unpacks the payload into values (see [`unpack`]).
    pub fn codes(&self, h: &FileHeader) -> Result<Vec<u16>> {
        unpack(
            &self.payload,
            h.pixel_format,
            h.bits_valid,
            h.msb_aligned,
            h.width as usize,
            h.height as usize,
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
}

/// Reads events from a stream. See the module docs.
pub struct StreamReader<R: Read> {
    src: R,
    buf: Vec<u8>,
    start: usize,
    offset: u64,
    eof: bool,
    header: FileHeader,
    /// Next expected index; None right after a restart.
    expected: Option<u64>,
    pending: VecDeque<Event>,
    done: bool,
}

enum ScanEnd {
    Frame,
    Header,
    Eof,
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

impl<R: Read> StreamReader<R> {
    /// Reads and checks the file header; fails (reading nothing more) if it is wrong.
    pub fn new(src: R) -> Result<Self> {
        let mut r = StreamReader {
            src,
            buf: Vec::new(),
            start: 0,
            offset: 0,
            eof: false,
            header: FileHeader::default(),
            expected: Some(0),
            pending: VecDeque::new(),
            done: false,
        };
        r.fill(FILE_HEADER_SIZE)?;
        r.header = FileHeader::decode(r.avail())?;
        r.consume(FILE_HEADER_SIZE);
        Ok(r)
    }

    /// The current file header (changes after [`Event::Restart`]).
    pub fn header(&self) -> &FileHeader {
        &self.header
    }

    fn avail(&self) -> &[u8] {
        &self.buf[self.start..]
    }

    fn consume(&mut self, n: usize) {
        let n = n.min(self.buf.len() - self.start);
        self.start += n;
        self.offset += n as u64;
    }

    /// Ensures `n` bytes are buffered unless the source ends first.
    fn fill(&mut self, n: usize) -> Result<()> {
        while self.buf.len() - self.start < n && !self.eof {
            if self.start > 0 {
                self.buf.drain(..self.start);
                self.start = 0;
            }
            let len = self.buf.len();
            let want = (n - len).max(1 << 16);
            self.buf.resize(len + want, 0);
            match self.src.read(&mut self.buf[len..]) {
                Ok(0) => {
                    self.buf.truncate(len);
                    self.eof = true;
                }
                Ok(k) => self.buf.truncate(len + k),
                Err(e) if e.kind() == ErrorKind::Interrupted => self.buf.truncate(len),
                Err(e) => {
                    self.buf.truncate(len);
                    return Err(Error::io("reading stream", e));
                }
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
        } else if self.avail()[..8] == FILE_MAGIC {
            self.fill(FILE_HEADER_SIZE)?;
            if self.avail().len() < FILE_HEADER_SIZE {
                return self.truncated(None);
            }
            match FileHeader::decode(self.avail()) {
                Ok(h) => {
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
        let rec = &self.avail()[..stride];
        let payload = rec[FRAME_HEADER_SIZE..FRAME_HEADER_SIZE + p].to_vec();
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

    /// True if a frame header or file header with a valid CRC starts at `j` of the buffer.
    fn valid_at(&mut self, j: usize) -> Result<bool> {
        self.fill(j + 8)?;
        let a = self.avail();
        if a.len() < j + 8 {
            return Ok(false);
        }
        if a[j..j + 8] == FRAME_MAGIC {
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

/// A damaged or truncated record in a [`VerifyReport`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Damage {
    /// Frame index, if known.
    pub index: Option<u64>,
    /// Byte offset.
    pub offset: u64,
    /// What was wrong.
    pub reason: String,
}

/// Result of [`verify`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VerifyReport {
    /// The (first) file header.
    pub header: FileHeader,
    /// Records with a valid header and payload CRC.
    pub frames: u64,
    /// First and last index seen.
    pub first_index: Option<u64>,
    /// Last index seen.
    pub last_index: Option<u64>,
    /// Frames missing from index gaps (dropped upstream, no damage seen).
    pub dropped: u64,
    /// The gaps, `from..to`.
    pub gaps: Vec<(u64, u64)>,
    /// Damaged records (header or payload), by index.
    pub corrupt: Vec<Damage>,
    /// Truncated records.
    pub truncated: Vec<Damage>,
    /// Bytes skipped while resynchronising.
    pub skipped_bytes: u64,
    /// Producer restarts (new file headers).
    pub restarts: u64,
    /// Header frame count disagrees with the records found: (declared, found).
    pub count_mismatch: Option<(u64, u64)>,
}

impl VerifyReport {
    /// True when nothing is damaged, truncated, skipped or dropped.
    pub fn clean(&self) -> bool {
        self.corrupt.is_empty()
            && self.truncated.is_empty()
            && self.dropped == 0
            && self.skipped_bytes == 0
            && self.count_mismatch.is_none()
    }
}

impl fmt::Display for VerifyReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let h = &self.header;
        writeln!(
            f,
            "stream: {} x {} {} ({} bits{}), payload {} B, stride {} B",
            h.width,
            h.height,
            h.pixel_format,
            h.bits_valid,
            if h.msb_aligned { ", MSB-aligned" } else { "" },
            h.payload_size(),
            h.stride()
        )?;
        write!(f, "frames: {} intact", self.frames)?;
        if let (Some(a), Some(b)) = (self.first_index, self.last_index) {
            write!(f, " (index {a}..{b})")?;
        }
        writeln!(f)?;
        writeln!(f, "dropped: {}", self.dropped)?;
        for (a, b) in &self.gaps {
            writeln!(f, "  gap: frames {a}..{} missing", b - 1)?;
        }
        writeln!(f, "corrupt: {}", self.corrupt.len())?;
        let id = |i: &Option<u64>| i.map_or("?".to_string(), |i| i.to_string());
        for d in &self.corrupt {
            writeln!(
                f,
                "  frame {} at byte {}: {}",
                id(&d.index),
                d.offset,
                d.reason
            )?;
        }
        writeln!(f, "truncated: {}", self.truncated.len())?;
        for d in &self.truncated {
            writeln!(
                f,
                "  frame {} at byte {}: {}",
                id(&d.index),
                d.offset,
                d.reason
            )?;
        }
        if self.skipped_bytes > 0 {
            writeln!(f, "skipped bytes: {}", self.skipped_bytes)?;
        }
        if self.restarts > 0 {
            writeln!(f, "producer restarts: {}", self.restarts)?;
        }
        if let Some((d, n)) = self.count_mismatch {
            writeln!(f, "header declares {d} frames, found {n}")?;
        }
        writeln!(f, "{}", if self.clean() { "clean" } else { "NOT clean" })
    }
}

/// Reads a whole stream and reports on it. Fails only if the file header is unusable or on an
/// I/O error.
pub fn verify<R: Read>(r: R) -> Result<VerifyReport> {
    let mut rd = StreamReader::new(r)?;
    let mut rep = VerifyReport {
        header: rd.header().clone(),
        frames: 0,
        first_index: None,
        last_index: None,
        dropped: 0,
        gaps: Vec::new(),
        corrupt: Vec::new(),
        truncated: Vec::new(),
        skipped_bytes: 0,
        restarts: 0,
        count_mismatch: None,
    };
    let mut records = 0u64;
    while let Some(ev) = rd.next_event()? {
        match ev {
            Event::Frame(fr) => {
                records += 1;
                rep.first_index.get_or_insert(fr.meta.index);
                rep.last_index = Some(fr.meta.index);
                if fr.payload_crc_ok {
                    rep.frames += 1;
                } else {
                    rep.corrupt.push(Damage {
                        index: Some(fr.meta.index),
                        offset: fr.offset,
                        reason: "payload CRC mismatch".into(),
                    });
                }
            }
            Event::Corrupt {
                index,
                offset,
                reason,
            } => {
                records += 1;
                rep.corrupt.push(Damage {
                    index,
                    offset,
                    reason,
                })
            }
            Event::Gap { from, to } => {
                rep.dropped += to - from;
                rep.gaps.push((from, to));
            }
            Event::Truncated {
                index,
                offset,
                have,
                need,
            } => {
                records += 1;
                rep.truncated.push(Damage {
                    index,
                    offset,
                    reason: format!("{have} of {need} bytes"),
                })
            }
            Event::Skipped { bytes, .. } => rep.skipped_bytes += bytes,
            Event::Restart(_) => rep.restarts += 1,
        }
    }
    let declared = rep.header.frame_count;
    if declared != 0 && rep.restarts == 0 && declared != records {
        rep.count_mismatch = Some((declared, records));
    }
    Ok(rep)
}

/// One frame pulled out of a stream by [`extract_frame`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Extracted {
    /// The file header in force for the frame.
    pub header: FileHeader,
    /// Its metadata.
    pub meta: FrameMeta,
    /// Unpacked values (`width·height`, row-major, `bits_valid` bits).
    #[serde(skip)]
    pub codes: Vec<u16>,
}

/// Finds the first frame with index `n` and unpacks it; fails if it is missing or its payload CRC
/// is wrong.
pub fn extract_frame<R: Read>(r: R, n: u64) -> Result<Extracted> {
    find_frame(r, Some(n))
}

/// Unpacks frame `n`, or with `None` the first intact frame of the stream; fails if it is missing
/// or its payload CRC is wrong.
pub fn find_frame<R: Read>(r: R, n: Option<u64>) -> Result<Extracted> {
    let mut rd = StreamReader::new(r)?;
    while let Some(ev) = rd.next_event()? {
        let Event::Frame(fr) = ev else { continue };
        let wanted = n.is_none_or(|n| n == fr.meta.index);
        if !wanted {
            continue;
        }
        if !fr.payload_crc_ok {
            if n.is_some() {
                return Err(Error::Format(format!(
                    "frame {}: payload CRC mismatch",
                    fr.meta.index
                )));
            }
            continue;
        }
        let codes = fr.codes(rd.header())?;
        return Ok(Extracted {
            header: rd.header().clone(),
            meta: fr.meta,
            codes,
        });
    }
    Err(Error::Invalid(match n {
        Some(n) => format!("frame {n} is not in the stream (or is damaged)"),
        None => "the stream holds no intact frame".into(),
    }))
}
