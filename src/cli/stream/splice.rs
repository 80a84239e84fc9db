//! A stream written into a pipe (stdout or a FIFO) with one copy of each payload instead of two:
//! `vmsplice(2)` hands the payload's pages to the pipe and the reader copies them out, where a
//! `write` would first copy them into the pipe's own pages (2-3 ms per full Mono16 frame).
//!
//! The pipe then refers to the payload buffer itself, so the buffer must not change until the
//! reader has taken those bytes. A pipe holds at most its capacity (1 MiB, [`super::output`]'s
//! `grow_pipe`), so once [`RETAIN`] further frames of at least that size have gone in after it,
//! the reader has read every page of a payload; `psns stream` reuses a payload buffer only then,
//! and never frees one handed to the pipe (the last ones live until the process ends). Only
//! payloads at least the pipe's capacity (asked of the pipe at each one) are spliced: a stream's
//! frames are all one size, so the frames after a spliced one fill the pipe; smaller payloads,
//! the record header and padding are written as usual.

use std::fs::File;
use std::io::{IoSlice, Write};
use std::os::fd::AsRawFd;

/// Frames written after a spliced payload before its buffer may be used again. Two full frames
/// (20 MB of Mono16, 10 MB of Mono8) lie far beyond a pipe's 1 MiB, which leaves room for a
/// reader that passes the pages on through a pipe of its own (`tee`, `pv`).
pub(crate) const RETAIN: usize = 2;

/// Slices at least this long are spliced (frame payloads); shorter ones are written.
const SPLICE_FROM: usize = 64 << 10;

/// The write end of a pipe, or any other descriptor when splicing is off.
pub(crate) struct PipeOut {
    file: File,
    /// Payload slices given to [`Write::write_vectored`] are spliced; their buffers stay
    /// untouched for [`RETAIN`] more frames (the caller's promise).
    splice: bool,
}

/// True when `f` is a pipe or FIFO.
pub(crate) fn is_pipe(f: &File) -> bool {
    use std::os::unix::fs::FileTypeExt;
    f.metadata().is_ok_and(|m| m.file_type().is_fifo())
}

impl PipeOut {
    /// Writes to `file`, copying everything until [`Self::splice_payloads`].
    pub(crate) fn new(file: File) -> Self {
        PipeOut {
            file,
            splice: false,
        }
    }

    /// Splices payloads from now on when the descriptor is a pipe; returns whether it does.
    /// The caller then keeps each payload buffer unchanged and alive for [`RETAIN`] more frames.
    pub(crate) fn splice_payloads(&mut self) -> bool {
        self.splice = cfg!(target_os = "linux") && is_pipe(&self.file);
        self.splice
    }

    #[cfg(target_os = "linux")]
    fn vmsplice(&self, b: &[u8]) -> std::io::Result<usize> {
        let iov = libc::iovec {
            iov_base: b.as_ptr() as *mut libc::c_void,
            iov_len: b.len(),
        };
        // SAFETY: one iovec over a live slice; without SPLICE_F_GIFT the kernel only takes
        // references to the pages, which the caller keeps unchanged (the type's contract)
        let n = unsafe { libc::vmsplice(self.file.as_raw_fd(), &iov, 1, 0) };
        if n < 0 {
            Err(std::io::Error::last_os_error())
        } else {
            Ok(n as usize)
        }
    }

    /// The pipe's capacity now (a reader may have grown it); unknown: too large to splice.
    #[cfg(target_os = "linux")]
    fn capacity(&self) -> usize {
        // SAFETY: fcntl on a descriptor this value owns
        let n = unsafe { libc::fcntl(self.file.as_raw_fd(), libc::F_GETPIPE_SZ) };
        if n > 0 {
            n as usize
        } else {
            usize::MAX
        }
    }

    #[cfg(not(target_os = "linux"))]
    fn capacity(&self) -> usize {
        usize::MAX
    }

    #[cfg(not(target_os = "linux"))]
    fn vmsplice(&self, _: &[u8]) -> std::io::Result<usize> {
        Err(std::io::Error::from(std::io::ErrorKind::Unsupported))
    }
}

impl Write for PipeOut {
    /// Copies (a buffered writer's own buffer comes here and is reused at once).
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.file.write(b)
    }

    /// Splices the first slice when it is a payload, else writes the slices up to the next
    /// payload.
    fn write_vectored(&mut self, bufs: &[IoSlice<'_>]) -> std::io::Result<usize> {
        let Some(first) = bufs.iter().position(|b| !b.is_empty()) else {
            return Ok(0);
        };
        let bufs = &bufs[first..];
        let from = match self.splice {
            true => SPLICE_FROM.max(self.capacity()),
            false => usize::MAX,
        };
        if bufs[0].len() >= from {
            return self.vmsplice(&bufs[0]);
        }
        let small = bufs
            .iter()
            .position(|b| b.len() >= from)
            .unwrap_or(bufs.len());
        self.file.write_vectored(&bufs[..small])
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    /// Payloads, headers and pads through a spliced pipe arrive whole and in order, however
    /// the pipe splits them.
    #[test]
    fn spliced_pipe_carries_every_byte_in_order() {
        let (mut rx, tx) = std::io::pipe().unwrap();
        let mut out = PipeOut::new(File::from(std::os::fd::OwnedFd::from(tx)));
        assert!(out.splice_payloads());
        let frames: Vec<Vec<u8>> = (0..4u8)
            .map(|k| {
                (0..300_000u32)
                    .map(|i| (i as u8) ^ k.wrapping_mul(37))
                    .collect()
            })
            .collect();
        let reader = std::thread::spawn(move || {
            let mut all = Vec::new();
            rx.read_to_end(&mut all).unwrap();
            all
        });
        let mut expect = Vec::new();
        for (k, p) in frames.iter().enumerate() {
            let hdr = [k as u8; 100];
            let pad = [0u8; 28];
            let mut parts = [IoSlice::new(&hdr), IoSlice::new(p), IoSlice::new(&pad)];
            let mut parts = &mut parts[..];
            while !parts.is_empty() {
                let n = out.write_vectored(parts).unwrap();
                assert!(n > 0);
                IoSlice::advance_slices(&mut parts, n);
            }
            expect.extend_from_slice(&hdr);
            expect.extend_from_slice(p);
            expect.extend_from_slice(&pad);
        }
        drop(out);
        let got = reader.join().unwrap();
        assert_eq!(got.len(), expect.len());
        assert!(got == expect, "spliced bytes differ from those written");
    }

    /// A payload smaller than the pipe's capacity is copied: the pipe could still hold it when
    /// the frames after it are in, so its buffer may change at once without the reader seeing it.
    #[test]
    fn payloads_smaller_than_the_pipe_are_copied() {
        use std::os::fd::AsRawFd;
        let (mut rx, tx) = std::io::pipe().unwrap();
        crate::cli::stream::grow_pipe(tx.as_raw_fd());
        let mut out = PipeOut::new(File::from(std::os::fd::OwnedFd::from(tx)));
        assert!(out.splice_payloads());
        assert!(out.capacity() >= 1 << 20, "{}", out.capacity());
        let mut payload: Vec<u8> = (0..300_000u32).map(|i| (i % 251) as u8).collect();
        let want = payload.clone();
        let mut written = 0;
        while written < payload.len() {
            written += out
                .write_vectored(&[IoSlice::new(&payload[written..])])
                .unwrap();
        }
        payload.iter_mut().for_each(|b| *b = 0xff);
        drop(out);
        let mut got = Vec::new();
        rx.read_to_end(&mut got).unwrap();
        assert!(
            got == want,
            "the reader saw the buffer change after the write"
        );
    }

    /// A regular file is never spliced.
    #[test]
    fn files_are_not_spliced() {
        let mut out = PipeOut::new(tempfile::tempfile().unwrap());
        assert!(!out.splice_payloads());
    }
}
