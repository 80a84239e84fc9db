//! `psns verify`: every record of a stream checked, damage listed, a status for the whole.

use super::*;

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
    /// producer killed between records or while writing the last one (which is then cut
    /// short), one still writing, or a pipe whose trajectory came from stdin (see
    /// `docs/stream-format.md`).
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
    /// Truncated records: records cut short with intact records after them, or a cut-short
    /// last record of a stream its header declares finished (frame count set).
    pub truncated: Vec<Damage>,
    /// The last record, cut short at the end of an input whose header frame count is 0: its
    /// producer was killed while writing it, or is still writing. Not damage: the records
    /// before it are the stream so far.
    pub cut_short: Option<Damage>,
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

    pub(super) fn compute_status(&self) -> VerifyStatus {
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
        if let Some(d) = &self.cut_short {
            writeln!(
                f,
                "cut short: the last record, frame {} at byte {}: {} (its producer was killed \
                 while writing it, or is still writing)",
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
    /// The last event so far is a record cut short.
    tail_truncated: bool,
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
                cut_short: None,
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
            tail_truncated: false,
        }
    }

    /// Counts one event of [`StreamReader::next_event`]; returns the damage it records, if any.
    pub fn record(&mut self, ev: &Event) -> Option<Damage> {
        self.tail_truncated = matches!(ev, Event::Truncated { .. });
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
        // a stream that says nothing of its end (count 0) and stops inside a record was cut
        // off while that record was being written: unfinished, not damaged
        if self.tail_truncated && rep.header.frame_count == 0 && rep.restarts == 0 {
            rep.cut_short = rep.truncated.pop();
        }
        let declared = match (rep.header.frame_count, self.end_frames) {
            (0, Some(n)) => n,
            (d, _) => d,
        };
        let records = self.records - u64::from(rep.cut_short.is_some());
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
