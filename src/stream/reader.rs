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

/// True for the error of a damaged first file header (see [`HEADER_DAMAGED`]).
pub fn header_damaged(e: &Error) -> bool {
    matches!(e, Error::Format(m) if m.starts_with(HEADER_DAMAGED))
}

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
            return Err(Error::Format(format!(
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
        return Err(Error::Format(format!("{HEADER_DAMAGED} (CRC mismatch)")));
    }
    FileHeader::decode(a)
}

/// Geometry given by the user for degraded mode ([`StreamReader::new_recovering`]); `None`
/// fields are inferred.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RecoverHint {
    /// Width in pixels.
    pub width: Option<u32>,
    /// Height in pixels.
    pub height: Option<u32>,
    /// Payload pixel format.
    pub pixel_format: Option<PixelFormat>,
}

/// How a damaged file header was replaced in degraded mode.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Recovery {
    /// Why the header was not usable.
    pub damage: String,
    /// Where the geometry came from (stride between frames, payload CRC, header fields, user).
    pub geometry: String,
    /// Header fields replaced by defaults because they were invalid.
    pub defaults: Vec<String>,
}

impl fmt::Display for Recovery {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}; geometry {}", self.damage, self.geometry)?;
        if !self.defaults.is_empty() {
            write!(f, "; defaults used for {}", self.defaults.join(", "))?;
        }
        Ok(())
    }
}

/// Most bytes degraded mode buffers while looking for two frame headers.
const RECOVER_SCAN_MAX: usize = 256 << 20;

/// A frame header with a valid CRC found while recovering.
struct Found {
    pos: usize,
    index: u64,
    pcrc: u32,
}

fn frames_in(buf: &[u8], want: usize) -> Vec<Found> {
    let mut out = Vec::new();
    let mut from = 0;
    while out.len() < want {
        let Some(i) = find(&buf[from..], &FRAME_MAGIC) else {
            break;
        };
        let j = from + i;
        if buf.len() >= j + FRAME_HEADER_SIZE {
            if let Ok((m, pcrc)) = FrameMeta::decode(&buf[j..]) {
                out.push(Found {
                    pos: j,
                    index: m.index,
                    pcrc,
                });
            }
        }
        from = j + 1;
    }
    out
}

/// Payload lengths in `lo..=hi` (capped to the data) whose CRC is `pcrc`.
fn crc_lengths(data: &[u8], lo: usize, hi: usize, pcrc: u32) -> Vec<usize> {
    let hi = hi.min(data.len());
    if lo > hi {
        return Vec::new();
    }
    let mut h = crc32fast::Hasher::new();
    h.update(&data[..lo]);
    let mut out = Vec::new();
    for len in lo..=hi {
        if len > lo {
            h.update(&data[len - 1..len]);
        }
        if len > 0 && h.clone().finalize() == pcrc {
            out.push(len);
        }
    }
    out
}

fn u32_le(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes(b[o..o + 4].try_into().expect("4 bytes"))
}
fn u64_le(b: &[u8], o: usize) -> u64 {
    u64::from_le_bytes(b[o..o + 8].try_into().expect("8 bytes"))
}

/// Infers the file header of a stream whose header is damaged. `buf` starts at the stream's
/// start; `eof` says whether it holds the whole stream. Returns the header, where reading starts
/// and the account of what was inferred.
fn infer_header(
    buf: &[u8],
    eof: bool,
    hint: &RecoverHint,
    damage: String,
) -> Result<(FileHeader, usize, Recovery)> {
    let hb: Vec<u8> = {
        let mut v = buf[..buf.len().min(FILE_HEADER_SIZE)].to_vec();
        v.resize(FILE_HEADER_SIZE, 0);
        v
    };
    let (w_s, h_s, code_s) = (u32_le(&hb, 20), u32_le(&hb, 24), u32_le(&hb, 28));
    let (p_s, s_s) = (u64_le(&hb, 48), u64_le(&hb, 56));
    let found = frames_in(buf, 3);
    let mut how: Vec<String> = Vec::new();
    // stride: between the first two frame headers, else from the first one's position
    let page = FILE_HEADER_SIZE as u64;
    let mut stride: Option<u64> = None;
    if let [a, b, ..] = found.as_slice() {
        let (d, di) = ((b.pos - a.pos) as u64, b.index.wrapping_sub(a.index));
        if b.index > a.index && d % di == 0 && (d / di) % page == 0 && d / di > 0 {
            stride = Some(d / di);
            how.push(format!(
                "stride {} B between frames {} and {}",
                d / di,
                a.index,
                b.index
            ));
        }
    }
    if let (None, Some(a)) = (stride, found.first()) {
        let off = a.pos as u64;
        if a.index > 0 && off > page && (off - page).is_multiple_of(a.index) {
            let s = (off - page) / a.index;
            if s.is_multiple_of(page) && s > 0 {
                stride = Some(s);
                how.push(format!("stride {s} B from frame {} at byte {off}", a.index));
            }
        } else if eof && found.len() == 1 {
            let s = (buf.len() - a.pos) as u64;
            if s.is_multiple_of(page) && s > 0 {
                stride = Some(s);
                how.push(format!("stride {s} B from the single frame's record"));
            }
        }
    }
    // exact payload size: the length whose CRC matches a frame header's payload CRC
    let mut payload: Option<u64> = None;
    for f in &found {
        let data = &buf[f.pos + FRAME_HEADER_SIZE..];
        let (lo, hi) = match stride {
            Some(s) => (
                (s as usize).saturating_sub(FILE_HEADER_SIZE + FRAME_HEADER_SIZE - 1),
                s as usize - FRAME_HEADER_SIZE,
            ),
            None => (0, data.len().min(super::MAX_PAYLOAD as usize)),
        };
        if lo > data.len() {
            continue;
        }
        if let [p] = crc_lengths(data, lo, hi, f.pcrc)[..] {
            payload = Some(p as u64);
            how.push(format!(
                "payload {p} B from the payload CRC of frame {}",
                f.index
            ));
            if stride.is_none() {
                stride = Some(stride_for(p as u64));
            }
            break;
        }
    }
    // the payload size to match: CRC-proven, else the header's if it fits the stride
    let target = payload.or_else(|| {
        let ok = stride.map_or(s_s == stride_for(p_s), |s| s == stride_for(p_s));
        (ok && p_s > 0 && p_s <= super::MAX_PAYLOAD).then(|| {
            how.push(format!("payload {p_s} B from the header (fits the stride)"));
            p_s
        })
    });
    let stored_fmt = PixelFormat::from_pfnc(code_s).ok();
    let fmts: Vec<PixelFormat> = match hint.pixel_format {
        Some(f) => vec![f],
        None => PixelFormat::ALL.to_vec(),
    };
    let size = |f: PixelFormat, w: u32, h: u32| {
        payload_size_checked(f, w as usize, h as usize).map(|p| p as u64)
    };
    // candidates (format, width, height) and how many stored fields each keeps
    let mut cands: Vec<(u32, PixelFormat, u32, u32)> = Vec::new();
    let n_of = |f: PixelFormat, p: u64| -> Vec<u64> {
        match f {
            PixelFormat::Mono8 => vec![p],
            PixelFormat::Mono16 => {
                if p.is_multiple_of(2) {
                    vec![p / 2]
                } else {
                    vec![]
                }
            }
            _ => vec![(2 * p) / 3, (2 * p) / 3 + 1]
                .into_iter()
                .filter(|&n| n.checked_mul(3).map(|x| x.div_ceil(2)) == Some(p))
                .collect(),
        }
    };
    let ok_dim = |x: u64| (1..=65_535).contains(&x);
    if let Some(p) = target {
        for &f in &fmts {
            let mut pairs: Vec<(u32, u32)> = Vec::new();
            let ws = hint.width.unwrap_or(w_s);
            let hs = hint.height.unwrap_or(h_s);
            pairs.push((ws, hs));
            for n in n_of(f, p) {
                if hint.width.is_none() && hs > 0 && n % hs as u64 == 0 && ok_dim(n / hs as u64) {
                    pairs.push(((n / hs as u64) as u32, hs));
                }
                if hint.height.is_none() && ws > 0 && n % ws as u64 == 0 && ok_dim(n / ws as u64) {
                    pairs.push((ws, (n / ws as u64) as u32));
                }
            }
            for (w, h) in pairs {
                if ok_dim(w as u64) && ok_dim(h as u64) && size(f, w, h) == Some(p) {
                    let score = (w == w_s) as u32
                        + (h == h_s) as u32
                        + (Some(f) == stored_fmt) as u32
                        + hint.width.is_some() as u32
                        + hint.height.is_some() as u32
                        + hint.pixel_format.is_some() as u32;
                    if !cands.iter().any(|c| (c.1, c.2, c.3) == (f, w, h)) {
                        cands.push((score, f, w, h));
                    }
                }
            }
        }
    } else if let (Some(f), Some(w), Some(h)) = (hint.pixel_format, hint.width, hint.height) {
        // no frame to check against: the user's geometry as given
        cands.push((3, f, w, h));
    }
    cands.sort_by_key(|c| std::cmp::Reverse(c.0));
    let said = format!(
        "frames found: {}; stride {}; payload {}; header fields say {w_s} x {h_s}, PFNC 0x{code_s:08X}, payload {p_s} B, stride {s_s} B",
        found.len(),
        stride.map_or("unknown".into(), |s| format!("{s} B")),
        target.map_or("unknown".into(), |p| format!("{p} B")),
    );
    let best = match cands.as_slice() {
        [] => {
            return Err(Error::Invalid(format!(
                "{damage}; cannot infer the frame geometry ({said}): give width, height and pixel format"
            )))
        }
        [a, b, ..] if a.0 == b.0 => {
            return Err(Error::Invalid(format!(
                "{damage}; frame geometry ambiguous ({} x {} {} or {} x {} {}; {said}): give width, height and pixel format",
                a.2, a.3, a.1, b.2, b.3, b.1
            )))
        }
        [a, ..] if a.0 < 2 => {
            return Err(Error::Invalid(format!(
                "{damage}; only {} x {} {} fits the frames, which disagrees with more than one header field ({said}): give width, height and pixel format",
                a.2, a.3, a.1
            )))
        }
        [a, ..] => *a,
    };
    let (_, fmt, width, height) = best;
    if let Some(s) = stride {
        if size(fmt, width, height).map(stride_for) != Some(s) {
            return Err(Error::Invalid(format!(
                "{damage}; {width} x {height} {fmt} has stride {} B but the frames found are {s} B apart",
                size(fmt, width, height).map_or(0, stride_for)
            )));
        }
    }
    let mut agree = Vec::new();
    for (name, given, same) in [
        ("width", hint.width.is_some(), width == w_s),
        ("height", hint.height.is_some(), height == h_s),
        (
            "pixel format",
            hint.pixel_format.is_some(),
            Some(fmt) == stored_fmt,
        ),
    ] {
        agree.push(if given {
            format!("{name} given")
        } else if same {
            format!("{name} from the header")
        } else {
            format!("{name} inferred (header field disagrees)")
        });
    }
    how.extend(agree);
    // the other fields: as stored when valid, else defaults
    let mut defaults = Vec::new();
    let bits = u16::from_le_bytes([hb[32], hb[33]]);
    let bits_ok = if fmt == PixelFormat::Mono8 {
        bits == 8
    } else {
        (1..=fmt.container_bits() as u16).contains(&bits)
    };
    let bits_valid = if bits_ok {
        bits as u8
    } else {
        defaults.push(format!("bits valid ({bits} -> {})", fmt.container_bits()));
        fmt.container_bits()
    };
    let align = u16::from_le_bytes([hb[34], hb[35]]);
    if align > 1 || (align == 1 && fmt != PixelFormat::Mono16) {
        defaults.push(format!("alignment ({align} -> LSB)"));
    }
    let msb_aligned = align == 1 && fmt == PixelFormat::Mono16;
    let mut ch = [0u8; 4];
    let mut angles_ok = true;
    for (k, c) in ch.iter_mut().enumerate() {
        *c = match i16::from_le_bytes([hb[36 + 2 * k], hb[37 + 2 * k]]) {
            0 => 0,
            45 => 1,
            90 => 2,
            135 => 3,
            _ => {
                angles_ok = false;
                0
            }
        };
    }
    let layout = match (angles_ok, MosaicLayout::from_channels(ch)) {
        (true, Ok(l)) => l,
        _ => {
            defaults.push("polarizer angles (IMX250MZR 90, 45, 135, 0)".into());
            MosaicLayout::IMX250MZR
        }
    };
    let sense = i16::from_le_bytes([hb[44], hb[45]]);
    let angle_sense = if sense == 1 || sense == -1 {
        sense
    } else {
        defaults.push(format!("angle sense ({sense} -> +1)"));
        1
    };
    let text = |off: usize, what: &str, defaults: &mut Vec<String>| {
        super::get_str(&hb, off, what).unwrap_or_else(|_| {
            defaults.push(format!("{what} (empty)"));
            String::new()
        })
    };
    let producer = text(160, "producer", &mut defaults);
    let preset = text(192, "preset", &mut defaults);
    let (jo, jl) = (u32_le(&hb, 224) as usize, u32_le(&hb, 228) as usize);
    let json = if jo == 0 && jl == 0 {
        String::new()
    } else if jo >= JSON_OFFSET
        && jo
            .checked_add(jl)
            .is_some_and(|e| e <= FILE_HEADER_SIZE - 4)
    {
        match std::str::from_utf8(&hb[jo..jo + jl]) {
            Ok(t) if !t.contains('\0') => t.to_string(),
            _ => {
                defaults.push("JSON (dropped)".into());
                String::new()
            }
        }
    } else {
        defaults.push("JSON (dropped)".into());
        String::new()
    };
    let mut cam = [0f64; 10];
    for (k, v) in cam.iter_mut().enumerate() {
        *v = f64::from_le_bytes(hb[80 + 8 * k..88 + 8 * k].try_into().expect("8 bytes"));
    }
    let end = u16::from_le_bytes([hb[46], hb[47]]);
    if end > 1 {
        defaults.push(format!("end status ({end} -> 0)"));
    }
    let header = FileHeader {
        version_minor: u16::from_le_bytes([hb[10], hb[11]]),
        width,
        height,
        pixel_format: fmt,
        bits_valid,
        msb_aligned,
        layout,
        angle_sense,
        frame_count: 0,
        aborted: end == 1,
        seed: u64_le(&hb, 72),
        camera: CameraConstants::from_array(cam),
        producer,
        preset,
        json,
    };
    header.validate()?;
    // read from the first frame if it lies inside the header's 4096 bytes, else after them
    let start = found
        .first()
        .map_or(FILE_HEADER_SIZE, |f| f.pos.min(FILE_HEADER_SIZE))
        .min(buf.len());
    let geometry = format!(
        "{width} x {height} {fmt} (payload {} B, stride {} B): {}",
        header.payload_size(),
        header.stride(),
        how.join(", ")
    );
    Ok((
        header,
        start,
        Recovery {
            damage,
            geometry,
            defaults,
        },
    ))
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
    /// ([`header_damaged`]) its geometry is inferred from the frames (the stride between two
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
            Err(e) if header_damaged(&e) => e.to_string(),
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

/// Verdict of [`verify`] (`psns verify` exit codes 0, 3 and 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum VerifyStatus {
    /// One stream, nothing damaged, and finished: its last frame carries [`FLAG_LAST`] or the
    /// header's frame count (patched by the writer on close) equals the records found.
    Clean,
    /// Nothing damaged, but the stream is not marked finished (count 0 and no LAST flag): a
    /// producer killed between records, one still writing, or a pipe whose trajectory came from
    /// stdin (see `docs/stream-format.md`).
    Unfinished,
    /// Nothing damaged, but the producer marked the stream aborted (an end record, or the header's
    /// mark): it stopped because of bad input, an I/O error or a signal.
    Aborted,
    /// Damaged records, drops, skipped bytes, a count mismatch, a damaged file header (degraded
    /// mode), or more than one stream in the input (a second file header: concatenated files or a
    /// producer restart).
    Damaged,
}

/// Result of [`verify`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VerifyReport {
    /// The verdict (see [`VerifyStatus`]).
    pub status: VerifyStatus,
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
    /// Byte offsets of the file headers after the first (one per restart).
    pub restart_offsets: Vec<u64>,
    /// Header frame count disagrees with the records found: (declared, found).
    pub count_mismatch: Option<(u64, u64)>,
    /// The last record is a frame with the LAST flag, or the header frame count matches, and the
    /// stream is not marked aborted.
    pub finished: bool,
    /// The producer marked the stream aborted: the end record's reason, or
    /// [`REASON_NOT_RECORDED`] when only the header carries the mark.
    pub aborted: Option<String>,
    /// Degraded mode: how a damaged file header was replaced (`None`: header intact).
    pub recovered: Option<Recovery>,
}

impl VerifyReport {
    /// True when nothing is damaged, truncated, skipped or dropped, the file header was intact
    /// and the input holds one stream (it may be unfinished).
    pub fn intact(&self) -> bool {
        self.corrupt.is_empty()
            && self.truncated.is_empty()
            && self.dropped == 0
            && self.skipped_bytes == 0
            && self.count_mismatch.is_none()
            && self.restarts == 0
            && self.recovered.is_none()
    }

    /// True when [`intact`](Self::intact) and finished ([`VerifyStatus::Clean`]).
    pub fn clean(&self) -> bool {
        self.status == VerifyStatus::Clean
    }

    fn compute_status(&self) -> VerifyStatus {
        if !self.intact() {
            VerifyStatus::Damaged
        } else if self.aborted.is_some() {
            VerifyStatus::Aborted
        } else if !self.finished {
            VerifyStatus::Unfinished
        } else {
            VerifyStatus::Clean
        }
    }
}

impl fmt::Display for VerifyReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let h = &self.header;
        if let Some(r) = &self.recovered {
            writeln!(f, "DEGRADED MODE: {r}")?;
        }
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
            let at: Vec<String> = self.restart_offsets.iter().map(|o| o.to_string()).collect();
            writeln!(
                f,
                "streams: {} (another file header at byte {}: concatenated files or a producer restart; frame indexes may repeat)",
                self.restarts + 1,
                at.join(", ")
            )?;
        }
        if let Some((d, n)) = self.count_mismatch {
            writeln!(f, "header declares {d} frames, found {n}")?;
        }
        match self.status {
            VerifyStatus::Clean => writeln!(f, "clean"),
            VerifyStatus::Unfinished => writeln!(
                f,
                "intact but UNFINISHED: header frame count 0 and no frame carries the LAST flag (producer killed or still writing)"
            ),
            VerifyStatus::Aborted => writeln!(
                f,
                "intact but ABORTED by its producer: {}",
                self.aborted.as_deref().unwrap_or(REASON_NOT_RECORDED)
            ),
            VerifyStatus::Damaged => match &self.aborted {
                Some(r) => writeln!(f, "NOT clean (and aborted by its producer: {r})"),
                None => writeln!(f, "NOT clean"),
            },
        }
    }
}

/// The reason of an abort marked in the file header only (the end record did not fit, e.g. on a
/// full disk).
pub const REASON_NOT_RECORDED: &str =
    "reason not recorded (the header is marked aborted, the end record is missing)";

/// Reads a whole stream and reports on it. Fails only if the file header is unusable or on an
/// I/O error.
pub fn verify<R: Read>(r: R) -> Result<VerifyReport> {
    verify_with(r, None)
}

/// [`verify`], in degraded mode with `Some(hint)` ([`StreamReader::new_recovering`]).
pub fn verify_with<R: Read>(r: R, recover: Option<&RecoverHint>) -> Result<VerifyReport> {
    let (mut rd, recovered) = match recover {
        Some(h) => StreamReader::new_recovering(r, h)?,
        None => (StreamReader::new(r)?, None),
    };
    let mut tally = VerifyTally::new(rd.header().clone(), recovered);
    while let Some(ev) = rd.next_event()? {
        tally.record(&ev);
    }
    Ok(tally.finish(rd.restart_offsets()))
}

/// The [`VerifyReport`] of a stream built event by event, for a reader that also uses the
/// frames (the Python package's stream iterator) and still reports damage as `psns verify` does.
#[derive(Clone, Debug)]
pub struct VerifyTally {
    rep: VerifyReport,
    records: u64,
    last_flag: bool,
    /// Frame records the end record says were written.
    end_frames: Option<u64>,
}

impl VerifyTally {
    /// An empty tally for a stream with this (first) file header.
    pub fn new(header: FileHeader, recovered: Option<Recovery>) -> Self {
        VerifyTally {
            rep: VerifyReport {
                status: VerifyStatus::Damaged,
                frames: 0,
                first_index: None,
                last_index: None,
                dropped: 0,
                gaps: Vec::new(),
                corrupt: Vec::new(),
                truncated: Vec::new(),
                skipped_bytes: 0,
                restarts: 0,
                restart_offsets: Vec::new(),
                count_mismatch: None,
                finished: false,
                aborted: header.aborted.then(|| REASON_NOT_RECORDED.to_string()),
                header,
                recovered,
            },
            records: 0,
            last_flag: false,
            end_frames: None,
        }
    }

    /// Counts one event of [`StreamReader::next_event`]; returns the damage it records, if any.
    pub fn record(&mut self, ev: &Event) -> Option<Damage> {
        let rep = &mut self.rep;
        match ev {
            Event::Frame(fr) => {
                self.records += 1;
                self.last_flag = fr.meta.flags & FLAG_LAST != 0;
                rep.first_index.get_or_insert(fr.meta.index);
                rep.last_index = Some(fr.meta.index);
                if fr.payload_crc_ok {
                    rep.frames += 1;
                } else {
                    let d = Damage {
                        index: Some(fr.meta.index),
                        offset: fr.offset,
                        reason: "payload CRC mismatch".into(),
                    };
                    rep.corrupt.push(d.clone());
                    return Some(d);
                }
            }
            Event::Corrupt {
                index,
                offset,
                reason,
            } => {
                self.records += 1;
                self.last_flag = false;
                let d = Damage {
                    index: *index,
                    offset: *offset,
                    reason: reason.clone(),
                };
                rep.corrupt.push(d.clone());
                return Some(d);
            }
            Event::Gap { from, to } => {
                rep.dropped += to - from;
                rep.gaps.push((*from, *to));
            }
            Event::Truncated {
                index,
                offset,
                have,
                need,
            } => {
                self.records += 1;
                self.last_flag = false;
                let d = Damage {
                    index: *index,
                    offset: *offset,
                    reason: format!("{have} of {need} bytes"),
                };
                rep.truncated.push(d.clone());
                return Some(d);
            }
            Event::Skipped { bytes, .. } => rep.skipped_bytes += bytes,
            Event::Restart(_) => {
                rep.restarts += 1;
                self.last_flag = false;
            }
            Event::Aborted { frames, reason, .. } => {
                rep.aborted = Some(reason.clone());
                self.end_frames = Some(*frames);
                self.last_flag = false;
            }
        }
        None
    }

    /// The report so far, as if the stream ended here (`restart_offsets` from the reader).
    pub fn finish(&self, restart_offsets: &[u64]) -> VerifyReport {
        let mut rep = self.rep.clone();
        rep.restart_offsets = restart_offsets.to_vec();
        let declared = match (rep.header.frame_count, self.end_frames) {
            (0, Some(n)) => n,
            (d, _) => d,
        };
        let records = self.records;
        if (declared != 0 || self.end_frames.is_some()) && rep.restarts == 0 && declared != records
        {
            rep.count_mismatch = Some((declared, records));
        }
        rep.finished = rep.aborted.is_none()
            && (self.last_flag || (declared != 0 && rep.restarts == 0 && declared == records));
        rep.status = rep.compute_status();
        rep
    }
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
    /// Where the frame was found.
    #[serde(skip)]
    pub location: FrameLocation,
    /// Degraded mode: how a damaged file header was replaced.
    #[serde(skip)]
    pub recovered: Option<Recovery>,
}

/// Where [`find_frame_with`] found a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct FrameLocation {
    /// Byte offset of the record.
    pub offset: u64,
    /// Which stream of the input holds it: 1 = the first; n = after the (n−1)-th further file
    /// header (concatenated files or producer restarts).
    pub copy: u64,
    /// Streams in the whole input when [`FindOptions::count_copies`] was set (the input was read
    /// to its end), else `None`.
    pub copies: Option<u64>,
}

/// Options of [`find_frame_with`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FindOptions<'a> {
    /// Degraded mode with this geometry hint ([`StreamReader::new_recovering`]).
    pub recover: Option<&'a RecoverHint>,
    /// After the frame is found, read on to the end to count the streams in the input.
    pub count_copies: bool,
}

/// Finds the first frame with index `n` and unpacks it; fails if it is missing or its payload CRC
/// is wrong.
pub fn extract_frame<R: Read>(r: R, n: u64) -> Result<Extracted> {
    find_frame(r, Some(n))
}

/// Unpacks frame `n`, or with `None` the first intact frame of the stream; fails if it is missing
/// or its payload CRC is wrong.
pub fn find_frame<R: Read>(r: R, n: Option<u64>) -> Result<Extracted> {
    find_frame_with(r, n, FindOptions::default())
}

/// [`find_frame`] with options: degraded mode, counting the streams in the input. The first
/// stream (copy) that holds frame `n` is used; [`Extracted::location`] says which.
pub fn find_frame_with<R: Read>(r: R, n: Option<u64>, opts: FindOptions) -> Result<Extracted> {
    let (mut rd, recovered) = match opts.recover {
        Some(h) => StreamReader::new_recovering(r, h)?,
        None => (StreamReader::new(r)?, None),
    };
    let mut copy = 1u64;
    while let Some(ev) = rd.next_event()? {
        let fr = match ev {
            Event::Frame(fr) => fr,
            Event::Restart(_) => {
                copy += 1;
                continue;
            }
            _ => continue,
        };
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
        let header = rd.header().clone();
        let copies = if opts.count_copies {
            let mut c = copy;
            while let Some(ev) = rd.next_event()? {
                if let Event::Restart(_) = ev {
                    c += 1;
                }
            }
            Some(c)
        } else {
            None
        };
        return Ok(Extracted {
            header,
            meta: fr.meta,
            codes,
            location: FrameLocation {
                offset: fr.offset,
                copy,
                copies,
            },
            recovered,
        });
    }
    Err(Error::Invalid(match n {
        Some(n) => format!("frame {n} is not in the stream (or is damaged)"),
        None => "the stream holds no intact frame".into(),
    }))
}
