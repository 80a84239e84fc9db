//! `psns extract`: one frame found in a stream, by index or the first readable one.

use super::*;

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
    // the lowest and highest frame index seen, for the range of a frame that is not there
    let mut seen: Option<(u64, u64)> = None;
    while let Some(ev) = rd.next_event()? {
        let fr = match ev {
            Event::Frame(fr) => fr,
            Event::Restart(_) => {
                copy += 1;
                continue;
            }
            _ => continue,
        };
        let i = fr.meta.index;
        seen = Some(seen.map_or((i, i), |(lo, hi)| (lo.min(i), hi.max(i))));
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
    if let (Some(n), Some((lo, hi))) = (n, seen) {
        if !(lo..=hi).contains(&n) {
            return Err(Error::OutOfRange {
                name: "frame".into(),
                value: n.to_string(),
                allowed: format!("{lo}..{hi}, the stream's frames"),
            });
        }
    }
    Err(Error::Invalid(match n {
        Some(n) => format!("frame {n} is not in the stream (or is damaged)"),
        None => "the stream holds no intact frame".into(),
    }))
}
