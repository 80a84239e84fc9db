//! Degraded mode: a stream whose first file header is damaged, its geometry inferred from the
//! frames that follow (the stride between frame magics, the CRCs of candidate payload sizes).

use super::*;
use crate::sensor::packing::pixel_counts;

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
pub(super) const RECOVER_SCAN_MAX: usize = 256 << 20;

/// A frame header with a valid CRC found while recovering.
pub(super) struct Found {
    pub(super) pos: usize,
    pub(super) index: u64,
    pub(super) pcrc: u32,
}

pub(super) fn frames_in(buf: &[u8], want: usize) -> Vec<Found> {
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
pub(super) fn crc_lengths(data: &[u8], lo: usize, hi: usize, pcrc: u32) -> Vec<usize> {
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

pub(super) fn u32_le(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes(b[o..o + 4].try_into().expect("4 bytes"))
}
pub(super) fn u64_le(b: &[u8], o: usize) -> u64 {
    u64::from_le_bytes(b[o..o + 8].try_into().expect("8 bytes"))
}

/// Infers the file header of a stream whose header is damaged. `buf` starts at the stream's
/// start; `eof` says whether it holds the whole stream. Returns the header, where reading starts
/// and the account of what was inferred.
pub(super) fn infer_header(
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
    let stored = Stored::read(&hb);
    let found = frames_in(buf, 3);
    let mut how: Vec<String> = Vec::new();
    let mut stride = stride_between(buf, &found, eof, &mut how);
    let payload = payload_by_crc(buf, &found, &mut stride, &mut how);
    // the payload size to match: CRC-proven, else the header's if it fits the stride
    let (p_s, s_s) = (stored.payload, stored.stride);
    let target = payload.or_else(|| {
        let ok = stride.map_or(s_s == stride_for(p_s), |s| s == stride_for(p_s));
        (ok && p_s > 0 && p_s <= crate::stream::MAX_PAYLOAD).then(|| {
            how.push(format!("payload {p_s} B from the header (fits the stride)"));
            p_s
        })
    });
    let cands = candidates(target, hint, &stored);
    let (w_s, h_s, code_s) = (stored.width, stored.height, stored.code);
    let said = format!(
        "frames found: {}; stride {}; payload {}; header fields say {w_s} x {h_s}, PFNC 0x{code_s:08X}, payload {p_s} B, stride {s_s} B",
        found.len(),
        stride.map_or("unknown".into(), |s| format!("{s} B")),
        target.map_or("unknown".into(), |p| format!("{p} B")),
    );
    let (fmt, width, height) = best_candidate(&cands, &damage, &said)?;
    if let Some(s) = stride {
        let size = payload_size_checked(fmt, width as usize, height as usize).map(|p| p as u64);
        if size.map(stride_for) != Some(s) {
            return Err(Error::Invalid(format!(
                "{damage}; {width} x {height} {fmt} has stride {} B but the frames found are {s} B apart",
                size.map_or(0, stride_for)
            )));
        }
    }
    for (name, given, same) in [
        ("width", hint.width.is_some(), width == w_s),
        ("height", hint.height.is_some(), height == h_s),
        (
            "pixel format",
            hint.pixel_format.is_some(),
            Some(fmt) == stored.format(),
        ),
    ] {
        how.push(if given {
            format!("{name} given")
        } else if same {
            format!("{name} from the header")
        } else {
            format!("{name} inferred (header field disagrees)")
        });
    }
    let mut defaults = Vec::new();
    let header = other_fields(&hb, fmt, width, height, &mut defaults);
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

/// The geometry fields of a damaged file header, as stored.
struct Stored {
    width: u32,
    height: u32,
    code: u32,
    payload: u64,
    stride: u64,
}

impl Stored {
    fn read(hb: &[u8]) -> Stored {
        Stored {
            width: u32_le(hb, 20),
            height: u32_le(hb, 24),
            code: u32_le(hb, 28),
            payload: u64_le(hb, 48),
            stride: u64_le(hb, 56),
        }
    }

    /// The stored pixel format, if its code is one.
    fn format(&self) -> Option<PixelFormat> {
        PixelFormat::from_pfnc(self.code).ok()
    }
}

/// The stride: between the first two frame headers found, else from the first one's position
/// (or, at the end of the data, from the single frame's record).
fn stride_between(buf: &[u8], found: &[Found], eof: bool, how: &mut Vec<String>) -> Option<u64> {
    let page = FILE_HEADER_SIZE as u64;
    if let [a, b, ..] = found {
        let (d, di) = ((b.pos - a.pos) as u64, b.index.wrapping_sub(a.index));
        if b.index > a.index && d % di == 0 && (d / di) % page == 0 && d / di > 0 {
            how.push(format!(
                "stride {} B between frames {} and {}",
                d / di,
                a.index,
                b.index
            ));
            return Some(d / di);
        }
    }
    let a = found.first()?;
    let off = a.pos as u64;
    if a.index > 0 && off > page && (off - page).is_multiple_of(a.index) {
        let s = (off - page) / a.index;
        if s.is_multiple_of(page) && s > 0 {
            how.push(format!("stride {s} B from frame {} at byte {off}", a.index));
            return Some(s);
        }
    } else if eof && found.len() == 1 {
        let s = (buf.len() - a.pos) as u64;
        if s.is_multiple_of(page) && s > 0 {
            how.push(format!("stride {s} B from the single frame's record"));
            return Some(s);
        }
    }
    None
}

/// The exact payload size: the only length (within the stride, if known) whose CRC matches a
/// frame header's payload CRC; sets the stride from it when none was found.
fn payload_by_crc(
    buf: &[u8],
    found: &[Found],
    stride: &mut Option<u64>,
    how: &mut Vec<String>,
) -> Option<u64> {
    for f in found {
        let data = &buf[f.pos + FRAME_HEADER_SIZE..];
        let (lo, hi) = match *stride {
            Some(s) => (
                (s as usize).saturating_sub(FILE_HEADER_SIZE + FRAME_HEADER_SIZE - 1),
                s as usize - FRAME_HEADER_SIZE,
            ),
            None => (0, data.len().min(crate::stream::MAX_PAYLOAD as usize)),
        };
        if lo > data.len() {
            continue;
        }
        if let [p] = crc_lengths(data, lo, hi, f.pcrc)[..] {
            how.push(format!(
                "payload {p} B from the payload CRC of frame {}",
                f.index
            ));
            if stride.is_none() {
                *stride = Some(stride_for(p as u64));
            }
            return Some(p as u64);
        }
    }
    None
}

/// The geometries (score, format, width, height) whose payload is `target` bytes, each scored
/// by the stored and given fields it keeps, best first; without a target, the user's geometry.
fn candidates(
    target: Option<u64>,
    hint: &RecoverHint,
    stored: &Stored,
) -> Vec<(u32, PixelFormat, u32, u32)> {
    let (w_s, h_s) = (stored.width, stored.height);
    let stored_fmt = stored.format();
    let fmts: Vec<PixelFormat> = match hint.pixel_format {
        Some(f) => vec![f],
        None => PixelFormat::ALL.to_vec(),
    };
    let size = |f: PixelFormat, w: u32, h: u32| {
        payload_size_checked(f, w as usize, h as usize).map(|p| p as u64)
    };
    let mut cands: Vec<(u32, PixelFormat, u32, u32)> = Vec::new();
    let ok_dim = |x: u64| (1..=65_535).contains(&x);
    if let Some(p) = target {
        for &f in &fmts {
            let mut pairs: Vec<(u32, u32)> = Vec::new();
            let ws = hint.width.unwrap_or(w_s);
            let hs = hint.height.unwrap_or(h_s);
            pairs.push((ws, hs));
            for n in pixel_counts(f, p) {
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
    cands
}

/// The one best candidate, or why there is none (`said`: what the frames and the header say).
fn best_candidate(
    cands: &[(u32, PixelFormat, u32, u32)],
    damage: &str,
    said: &str,
) -> Result<(PixelFormat, u32, u32)> {
    match cands {
        [] => Err(Error::Invalid(format!(
            "{damage}; cannot infer the frame geometry ({said}): give width, height and pixel format"
        ))),
        [a, b, ..] if a.0 == b.0 => Err(Error::Invalid(format!(
            "{damage}; frame geometry ambiguous ({} x {} {} or {} x {} {}; {said}): give width, height and pixel format",
            a.2, a.3, a.1, b.2, b.3, b.1
        ))),
        [a, ..] if a.0 < 2 => Err(Error::Invalid(format!(
            "{damage}; only {} x {} {} fits the frames, which disagrees with more than one header field ({said}): give width, height and pixel format",
            a.2, a.3, a.1
        ))),
        [a, ..] => Ok((a.1, a.2, a.3)),
    }
}

/// The header with the inferred geometry and its other fields as stored when valid, else
/// defaults (each listed in `defaults`).
fn other_fields(
    hb: &[u8],
    fmt: PixelFormat,
    width: u32,
    height: u32,
    defaults: &mut Vec<String>,
) -> FileHeader {
    // the other fields: as stored when valid, else defaults
    let bits = u16::from_le_bytes([hb[32], hb[33]]);
    let bits_ok = fmt.bits_valid_ok(bits);
    let bits_valid = if bits_ok {
        bits as u8
    } else {
        defaults.push(format!("bits valid ({bits} -> {})", fmt.container_bits()));
        fmt.container_bits()
    };
    let align = u16::from_le_bytes([hb[34], hb[35]]);
    let msb_ok = fmt.info().msb_alignable;
    if align > 1 || (align == 1 && !msb_ok) {
        defaults.push(format!("alignment ({align} -> LSB)"));
    }
    let msb_aligned = align == 1 && msb_ok;
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
        crate::stream::get_str(hb, off, what).unwrap_or_else(|_| {
            defaults.push(format!("{what} (empty)"));
            String::new()
        })
    };
    let producer = text(160, "producer", defaults);
    let preset = text(192, "preset", defaults);
    let (jo, jl) = (u32_le(hb, 224) as usize, u32_le(hb, 228) as usize);
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
    FileHeader {
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
        seed: u64_le(hb, 72),
        camera: CameraConstants::from_array(cam),
        producer,
        preset,
        json,
    }
}
