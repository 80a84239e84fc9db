//! Stream writer: file header, then whole records (header | payload | zero pad), one vectored
//! write and one flush per frame so a reader can follow the stream as it grows.

use super::{
    crc32, EndRecord, FileHeader, FrameMeta, FILE_HEADER_SIZE, FLAG_DROPPED, FRAME_HEADER_SIZE,
};
use crate::error::{Error, Result};
use crate::sensor::packing::{pack, payload_size};
use std::fs::File;
use std::io::{IoSlice, Seek, SeekFrom, Write};
use std::path::Path;

/// Writes a stream to any `Write` (file, FIFO, stdout). Never seeks.
///
/// A closed reader surfaces as [`Error::Io`] with kind `BrokenPipe`
/// ([`Error::is_broken_pipe`]); the caller should then end quietly.
pub struct StreamWriter<W: Write> {
    w: W,
    header: FileHeader,
    /// Zeros for the pad after each payload.
    pad: Vec<u8>,
    packed: Vec<u8>,
    last_index: Option<u64>,
    frames: u64,
    sensor_bits: u8,
    /// A write failed: part of a record may have gone out, so the position is unknown.
    broken: bool,
}

impl<W: Write> StreamWriter<W> {
    /// Writes the file header (its `frame_count` as given, normally 0) and returns the writer.
    ///
    /// `header.bits_valid` is the payload's valid bits; for Mono8 it must be 8 and
    /// [`write_frame`](Self::write_frame) takes codes at the sensor bit depth given by
    /// [`with_sensor_bits`](Self::with_sensor_bits) (default 12).
    pub fn new(mut w: W, header: &FileHeader) -> Result<Self> {
        let b = header.encode()?;
        w.write_all(&b)
            .and_then(|_| w.flush())
            .map_err(|e| Error::io("writing stream file header", e))?;
        let p = payload_size(
            header.pixel_format,
            header.width as usize,
            header.height as usize,
        );
        Ok(StreamWriter {
            w,
            header: header.clone(),
            pad: vec![0u8; header.stride() as usize - FRAME_HEADER_SIZE - p],
            packed: Vec::new(),
            last_index: None,
            frames: 0,
            broken: false,
            sensor_bits: if header.pixel_format.info().shifts_down {
                12
            } else {
                header.bits_valid
            },
        })
    }

    /// Mono8 only: bit depth of the codes given to [`write_frame`](Self::write_frame)
    /// (8..16; 8 stores them unchanged, 12 keeps code >> 4).
    pub fn with_sensor_bits(mut self, bits: u8) -> Self {
        if self.header.pixel_format.info().shifts_down {
            self.sensor_bits = bits;
        }
        self
    }

    /// The header written.
    pub fn header(&self) -> &FileHeader {
        &self.header
    }

    /// The writer the stream goes into (to tune it; writing to it directly would break the
    /// stream).
    pub fn get_mut(&mut self) -> &mut W {
        &mut self.w
    }

    /// Frames written so far.
    pub fn frames_written(&self) -> u64 {
        self.frames
    }

    /// Packs `codes` (width·height values, row-major) and writes one record.
    pub fn write_frame(&mut self, meta: &FrameMeta, codes: &[u16]) -> Result<()> {
        let n = self.header.width as usize * self.header.height as usize;
        if codes.len() != n {
            return Err(Error::Invalid(format!(
                "frame has {} codes, the stream expects {} x {} = {n}",
                codes.len(),
                self.header.width,
                self.header.height
            )));
        }
        let mut packed = std::mem::take(&mut self.packed);
        let r = pack(
            codes,
            self.sensor_bits,
            self.header.pixel_format,
            self.header.msb_aligned,
            &mut packed,
        )
        .and_then(|_| self.write_payload(meta, &packed));
        self.packed = packed;
        r
    }

    /// Writes one record from an already packed payload. Indexes must increase; a jump sets
    /// [`FLAG_DROPPED`](super::FLAG_DROPPED).
    pub fn write_payload(&mut self, meta: &FrameMeta, payload: &[u8]) -> Result<()> {
        self.write_payload_crc(meta, payload, None)
    }

    /// [`Self::write_payload`] with the payload's CRC-32 already known (`Some`: computed by
    /// whoever made the payload, e.g. [`crate::sensor::packing::pack_crc32`] or
    /// [`crate::sensor::RawFrame::codes_crc32`], which take it while the bytes are in cache;
    /// checked against the payload in debug builds), or `None` to compute it here.
    pub fn write_payload_crc(
        &mut self,
        meta: &FrameMeta,
        payload: &[u8],
        crc: Option<u32>,
    ) -> Result<()> {
        let p = payload_size(
            self.header.pixel_format,
            self.header.width as usize,
            self.header.height as usize,
        );
        if payload.len() != p {
            return Err(Error::Invalid(format!(
                "payload of {} bytes, the stream expects {p}",
                payload.len()
            )));
        }
        let mut meta = *meta;
        if let Some(last) = self.last_index {
            if meta.index <= last {
                return Err(Error::Invalid(format!(
                    "frame index {} after {last} (indexes must increase)",
                    meta.index
                )));
            }
            if meta.index > last + 1 {
                meta.flags |= FLAG_DROPPED;
            }
        }
        debug_assert!(crc.is_none_or(|c| c == crc32(payload)), "payload CRC");
        let hdr = meta.encode(crc.unwrap_or_else(|| crc32(payload)));
        // header, payload and zero pad gathered by one vectored write: the payload is not copied
        let pad = &self.pad[..self.header.stride() as usize - FRAME_HEADER_SIZE - p];
        write_all_vectored(&mut self.w, &[&hdr[..], payload, pad])
            .and_then(|_| self.w.flush())
            .map_err(|e| {
                self.broken = true;
                Error::io(format!("writing stream frame {}", meta.index), e)
            })?;
        self.last_index = Some(meta.index);
        self.frames += 1;
        Ok(())
    }

    /// Marks the stream aborted: writes the [`EndRecord`] with `reason` after the last whole
    /// record and flushes. For a producer that stops because of a failure (bad input, I/O error,
    /// signal); a stream that ends normally gets no end record. Writes nothing and fails when an
    /// earlier write failed, since part of a record may then be out.
    pub fn abort(&mut self, reason: &str) -> Result<()> {
        if self.broken {
            return Err(Error::io(
                "writing the stream's end record",
                std::io::Error::other("an earlier write failed part-way"),
            ));
        }
        let rec = EndRecord::aborted(self.frames, reason).encode();
        self.w
            .write_all(&rec)
            .and_then(|_| self.w.flush())
            .map_err(|e| {
                self.broken = true;
                Error::io("writing the stream's end record", e)
            })
    }

    /// Flushes and returns the inner writer.
    pub fn finish(mut self) -> Result<W> {
        self.w
            .flush()
            .map_err(|e| Error::io("flushing stream", e))?;
        Ok(self.w)
    }
}

/// Writes every byte of `parts`, in order, with as few `write_vectored` calls as the writer
/// allows (`Write::write_all_vectored` is not stable).
fn write_all_vectored<W: Write>(w: &mut W, parts: &[&[u8]]) -> std::io::Result<()> {
    let mut bufs: Vec<IoSlice<'_>> = parts.iter().map(|p| IoSlice::new(p)).collect();
    let mut bufs = &mut bufs[..];
    IoSlice::advance_slices(&mut bufs, 0); // drop leading empty slices
    while !bufs.is_empty() {
        match w.write_vectored(bufs) {
            Ok(0) => {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::WriteZero,
                    "failed to write whole buffer",
                ))
            }
            Ok(n) => IoSlice::advance_slices(&mut bufs, n),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// A stream written to a path. On [`finish`](Self::finish) the frame count is patched into the
/// header if (and only if) the path is a regular file; FIFOs and character devices keep 0.
pub struct FileStreamWriter {
    inner: StreamWriter<File>,
}

impl FileStreamWriter {
    /// Creates (truncates) `path` — or opens a FIFO for writing — and writes the file header.
    pub fn create(path: impl AsRef<Path>, header: &FileHeader) -> Result<Self> {
        let path = path.as_ref();
        let f = std::fs::OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .open(path)
            .map_err(|e| Error::io(format!("creating {}", path.display()), e))?;
        Self::new(f, header)
    }

    /// Writes the file header into `file`, already opened for writing at its start (a new or
    /// emptied file, a FIFO or a device), and returns the writer.
    pub fn new(file: File, header: &FileHeader) -> Result<Self> {
        Ok(FileStreamWriter {
            inner: StreamWriter::new(file, header)?,
        })
    }

    /// See [`StreamWriter::with_sensor_bits`].
    pub fn with_sensor_bits(self, bits: u8) -> Self {
        FileStreamWriter {
            inner: self.inner.with_sensor_bits(bits),
        }
    }

    /// See [`StreamWriter::write_frame`].
    pub fn write_frame(&mut self, meta: &FrameMeta, codes: &[u16]) -> Result<()> {
        self.inner.write_frame(meta, codes)
    }

    /// See [`StreamWriter::write_payload`].
    pub fn write_payload(&mut self, meta: &FrameMeta, payload: &[u8]) -> Result<()> {
        self.inner.write_payload(meta, payload)
    }

    /// See [`StreamWriter::write_payload_crc`].
    pub fn write_payload_crc(
        &mut self,
        meta: &FrameMeta,
        payload: &[u8],
        crc: Option<u32>,
    ) -> Result<()> {
        self.inner.write_payload_crc(meta, payload, crc)
    }

    /// Frames written so far.
    pub fn frames_written(&self) -> u64 {
        self.inner.frames_written()
    }

    /// The open file's descriptor (to tune a FIFO's buffer).
    #[cfg(unix)]
    pub fn as_raw_fd(&self) -> std::os::fd::RawFd {
        std::os::fd::AsRawFd::as_raw_fd(&self.inner.w)
    }

    /// Flushes; for a regular file rewrites the header with the frame count. Returns the count.
    pub fn finish(self) -> Result<u64> {
        let n = self.inner.frames_written();
        let mut header = self.inner.header().clone();
        let mut f = self.inner.finish()?;
        if is_regular(&f) {
            header.frame_count = n;
            patch_header(&mut f, &header)
                .map_err(|e| Error::io("patching stream frame count", e))?;
        }
        Ok(n)
    }

    /// Ends a stream whose producer failed (bad input, I/O error, signal), so that every reader
    /// sees it aborted rather than finished: the frame count stays 0, and
    /// - a regular file loses a partly written record (cut back to the last whole one), gets the
    ///   [`EndRecord`] with `reason` and its header's `aborted` mark (which needs no new disk
    ///   space, so it lands even when the end record does not fit on a full disk);
    /// - a FIFO or device gets the end record if no write failed part-way.
    ///
    /// Every step is tried; the first failure is returned.
    pub fn abort(mut self, reason: &str) -> Result<u64> {
        let n = self.inner.frames_written();
        let regular = is_regular(&self.inner.w);
        let whole = FILE_HEADER_SIZE as u64 + n * self.inner.header.stride();
        let mut first: Option<Error> = None;
        if regular && self.inner.broken {
            let f = &mut self.inner.w;
            match f
                .set_len(whole)
                .and_then(|_| f.seek(SeekFrom::Start(whole)))
            {
                Ok(_) => self.inner.broken = false,
                Err(e) => first = Some(Error::io("cutting the partly written frame record", e)),
            }
        }
        if let Err(e) = self.inner.abort(reason) {
            if regular {
                // a partial end record would read as damage: cut it off
                let _ = self.inner.w.set_len(whole);
            }
            first.get_or_insert(e);
        }
        if regular {
            let mut header = self.inner.header.clone();
            header.frame_count = 0;
            header.aborted = true;
            if let Err(e) = patch_header(&mut self.inner.w, &header) {
                first.get_or_insert(Error::io("marking the stream aborted in its header", e));
            }
        }
        match first {
            None => Ok(n),
            Some(e) => Err(e),
        }
    }
}

fn is_regular(f: &File) -> bool {
    f.metadata().is_ok_and(|m| m.file_type().is_file())
}

/// Rewrites the file header at the start of `f` and returns to where it was.
fn patch_header(f: &mut File, header: &FileHeader) -> std::io::Result<()> {
    let b = header
        .encode()
        .map_err(|e| std::io::Error::other(e.to_string()))?;
    debug_assert_eq!(b.len(), FILE_HEADER_SIZE);
    let end = f.stream_position()?;
    f.seek(SeekFrom::Start(0))?;
    f.write_all(&b)?;
    f.seek(SeekFrom::Start(end))?;
    f.flush()
}
