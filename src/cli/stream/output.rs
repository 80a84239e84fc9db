//! Where the frames go: stdout, a path (regular file, FIFO, device), or a ROS 2 bag.

use super::*;

/// The output: stdout, or a path (regular file, FIFO, device) with the count patched on close,
/// or a ROS 2 bag.
pub(super) enum Output {
    Stdout(StreamWriter<BufWriter<std::io::StdoutLock<'static>>>),
    Path(FileStreamWriter),
    Bag(Box<crate::cli::bag::BagWriter>),
}

/// Asks the kernel for a 1 MiB buffer on a pipe or FIFO (the default 64 KiB wakes the reader
/// 160 times per 10 MB frame); anything else, or a refusal, leaves it as it is.
pub(crate) fn grow_pipe(fd: std::os::fd::RawFd) {
    #[cfg(target_os = "linux")]
    // SAFETY: fcntl on a descriptor this process holds open; F_SETPIPE_SZ fails harmlessly
    // (EBADF/EINVAL/EPERM) on non-pipes and over the limit
    unsafe {
        libc::fcntl(fd, libc::F_SETPIPE_SZ, 1 << 20);
    }
    #[cfg(not(target_os = "linux"))]
    let _ = fd;
}

impl Output {
    pub(super) fn open(
        path: &Path,
        header: &FileHeader,
        bag: Option<&crate::cli::bag::BagOptions>,
    ) -> Result<Self> {
        use std::os::fd::AsRawFd;
        if let Some(b) = bag {
            let enc = psns::ros2::ImageEncoding::of_pixel_format(header.pixel_format);
            let src = crate::cli::bag::BagSource::of_header(header, enc)?;
            Ok(Output::Bag(Box::new(crate::cli::bag::BagWriter::create(
                b, path, src,
            )?)))
        } else if path.as_os_str() == "-" {
            let out = std::io::stdout().lock();
            grow_pipe(out.as_raw_fd());
            let w = BufWriter::with_capacity(1 << 20, out);
            Ok(Output::Stdout(StreamWriter::new(w, header)?))
        } else {
            let w = FileStreamWriter::create(path, header)?;
            grow_pipe(w.as_raw_fd());
            Ok(Output::Path(w))
        }
    }
    /// Writes a frame; a bag's image message is completed in its payload buffer.
    pub(super) fn write(&mut self, r: &mut Rendered) -> Result<()> {
        match self {
            Output::Stdout(w) => w.write_payload_crc(&r.meta, r.payload.as_bytes(), r.crc),
            Output::Path(w) => w.write_payload_crc(&r.meta, r.payload.as_bytes(), r.crc),
            Output::Bag(w) => {
                let truth = r.truth.as_ref().map(|(d, a)| (&d[..], &a[..]));
                match &mut r.payload {
                    Payload::Message(m, _) => {
                        w.write_frame_message(&r.meta, bytemuck::cast_slice_mut(m), truth)
                    }
                    p => w.write_frame(&r.meta, p.as_bytes(), truth),
                }
            }
        }
    }
    pub(super) fn finish(self) -> Result<()> {
        match self {
            Output::Stdout(w) => w
                .finish()?
                .flush()
                .map_err(|e| Error::io("flushing stdout", e)),
            Output::Path(w) => w.finish().map(|_| ()),
            Output::Bag(w) => w.finish(),
        }
    }
    /// Marks the stream aborted ([`FileStreamWriter::abort`]); a bag is left unfinished (no
    /// footer, no `metadata.yaml`), which is how rosbag2 and MCAP readers tell a cut-off bag.
    pub(super) fn abort(self, reason: &str) -> Result<()> {
        match self {
            Output::Stdout(mut w) => {
                w.abort(reason)?;
                w.finish()?
                    .flush()
                    .map_err(|e| Error::io("flushing stdout", e))
            }
            Output::Path(w) => w.abort(reason).map(|_| ()),
            Output::Bag(w) => {
                eprintln!("psns: {}", w.leave_unfinished());
                Ok(())
            }
        }
    }
}
