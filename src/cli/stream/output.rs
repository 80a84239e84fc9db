//! The output of a recording (`psns stream`, `psns convert`, `psns recover`), chosen once: the
//! psns stream to stdout, a FIFO or device, or a file, or a ROS 2 bag (rosbag2 directory or bare
//! MCAP file). [`OutputSpec::check`] checks `--out` before any work ([`place`](super::place):
//! what may be written or replaced); [`OutputSpec::open`] opens it once the first frame is made;
//! the [`Output`] then takes frames, and is finished, aborted or abandoned, and says what it
//! leaves. Whoever makes the frames asks [`OutputSpec::frames`] how to make them and otherwise
//! knows nothing of the output.

use super::place::{Landing, Place};
use super::splice::{is_pipe, PipeOut};
use crate::cli::bag::{image_prefix_len, BagOptions, BagSource, BagWriter, Compression, McapBag};
use psns::error::{Error, Result};
use psns::ros2::ImageEncoding;
use psns::sensor::packing::{self, PixelFormat};
use psns::stream::{FileHeader, FileStreamWriter, FrameMeta, StreamWriter};
use std::fs::File;
use std::io::Write;
use std::path::Path;

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

/// A recording's output as the options give it, checked.
#[derive(Debug)]
pub(crate) struct OutputSpec {
    place: Place,
    bag: Option<BagOptions>,
}

/// How the frames of an output are made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct FrameKind {
    /// The payload's pixel format: the stream's, or a bag image's (mono8, or the codes as
    /// little-endian mono16).
    pub format: PixelFormat,
    /// A bag's mono16 image: u16 elements of room for the message's CDR prefix in front of the
    /// codes, which the bag fills in place (no copy of the pixels); 0 otherwise.
    pub lead: usize,
    /// Also the ground-truth DoLP and AoLP (a bag's `--truth-images`).
    pub truth: bool,
}

/// The pixels of one frame for [`Output::write`].
pub(crate) enum Pixels<'a> {
    /// The payload in the frame's pixel format.
    Bytes(&'a [u8]),
    /// A bag's image message made in place: `lead` bytes of room, then the pixel bytes.
    Message(&'a mut [u8], usize),
}

/// One frame for [`Output::write`].
pub(crate) struct OutFrame<'a> {
    pub meta: &'a FrameMeta,
    pub pixels: Pixels<'a>,
    /// The payload's CRC-32 when its maker took it; `None`: computed when needed.
    pub crc: Option<u32>,
    /// Ground-truth DoLP and AoLP (degrees).
    pub truth: Option<(&'a [f32], &'a [f32])>,
}

impl OutputSpec {
    /// Checks `--out` for the psns format (`bag` `None`) or a bag, before any work.
    pub(crate) fn check(out: &Path, bag: Option<BagOptions>) -> Result<Self> {
        let place = Place::check(out, bag.as_ref().map(|b| &b.kind))?;
        Ok(OutputSpec { place, bag })
    }

    /// Payload buffers the output may hold on to after they are written: [`super::splice::RETAIN`]
    /// for a psns stream into a pipe or FIFO, else 0.
    pub(crate) fn retains(&self) -> usize {
        match self.bag.is_none() && self.place.is_pipe() {
            true => super::splice::RETAIN,
            false => 0,
        }
    }

    /// A ROS 2 bag (else the psns format).
    pub(crate) fn is_bag(&self) -> bool {
        self.bag.is_some()
    }

    /// How to make frames for this output, for a stream described by `header`.
    pub(crate) fn frames(&self, header: &FileHeader) -> Result<FrameKind> {
        let Some(b) = &self.bag else {
            return Ok(FrameKind {
                format: header.pixel_format,
                lead: 0,
                truth: false,
            });
        };
        let enc = ImageEncoding::of_pixel_format(header.pixel_format);
        let format = enc.pixel_format().unwrap_or(header.pixel_format);
        let lead = if packing::codes_are_payload(format) {
            image_prefix_len(enc, header.width as usize, header.height as usize)? / 2
        } else {
            0
        };
        Ok(FrameKind {
            format,
            lead,
            truth: b.truth_images,
        })
    }

    /// Opens the output for a stream described by `header`: the psns stream's file header is
    /// written, or the bag's schemas and channels.
    pub(crate) fn open(self, header: &FileHeader) -> Result<Output> {
        use std::os::fd::AsRawFd;
        if let Some(note) = self.place.replacing_note() {
            eprintln!("psns: {note}");
        }
        let (file, landing) = self.place.open()?;
        let mut out = Output {
            sink: None,
            landing,
            bag: self.bag.is_some(),
            failed: false,
        };
        // a failure to start leaves nothing behind
        let sink = match (file, &self.bag) {
            (None, _) => {
                use std::os::fd::AsFd;
                let stdout = std::io::stdout();
                let _ = stdout.lock().flush();
                stdout
                    .as_fd()
                    .try_clone_to_owned()
                    .map_err(|e| Error::io("opening stdout", e))
                    .and_then(|fd| pipe_writer(File::from(fd), header))
            }
            (Some(f), None) if is_pipe(&f) => pipe_writer(f, header),
            (Some(f), None) => {
                grow_pipe(f.as_raw_fd());
                FileStreamWriter::new(f, header).map(Sink::File)
            }
            (Some(f), Some(b)) => {
                let enc = ImageEncoding::of_pixel_format(header.pixel_format);
                BagSource::of_header(header, enc)
                    .and_then(|src| BagWriter::create(b, out.landing.bag_file(f), src))
                    .map(|w| Sink::Bag(Box::new(w)))
            }
        };
        match sink {
            Ok(s) => {
                out.sink = Some(s);
                Ok(out)
            }
            Err(e) => {
                out.landing.discard();
                Err(e)
            }
        }
    }
}

impl OutputSpec {
    /// Opens a bag whose topics and messages the caller writes (`psns recover`), with
    /// `custom_data` for `metadata.yaml`.
    pub(crate) fn open_bag(
        self,
        compression: Compression,
        custom_data: Vec<(String, String)>,
    ) -> Result<RawBag> {
        if let Some(note) = self.place.replacing_note() {
            eprintln!("psns: {note}");
        }
        let (file, landing) = self.place.open()?;
        let Some(file) = file else {
            return Err(Error::Invalid("a bag is not written to stdout".into()));
        };
        match McapBag::create(landing.bag_file(file), compression, custom_data) {
            Ok(bag) => Ok(RawBag { bag, landing }),
            Err(e) => {
                landing.discard();
                Err(e)
            }
        }
    }
}

/// A bag of the caller's topics and messages, at its place.
pub(crate) struct RawBag {
    pub bag: McapBag,
    landing: Landing,
}

impl RawBag {
    /// The MCAP file as the finished bag has it.
    pub(crate) fn final_path(&self) -> std::path::PathBuf {
        self.landing.final_path()
    }

    /// Finishes the bag and puts it in place.
    pub(crate) fn finish(self) -> Result<()> {
        let RawBag { bag, landing } = self;
        match bag.finish() {
            Ok(()) => landing.commit(),
            Err(e) => {
                landing.discard();
                Err(e)
            }
        }
    }

    /// Gives the bag up: removes what was written.
    pub(crate) fn abandon(self) {
        let RawBag { bag, landing } = self;
        drop(bag);
        landing.discard();
    }
}

/// The psns stream to stdout or a FIFO, unbuffered (each record is one vectored write), the
/// payloads spliced once [`Output::splice_payloads`] says so.
fn pipe_writer(f: File, header: &FileHeader) -> Result<Sink> {
    use std::os::fd::AsRawFd;
    grow_pipe(f.as_raw_fd());
    StreamWriter::new(PipeOut::new(f), header).map(Sink::Stdout)
}

enum Sink {
    /// Stdout, or a FIFO: no header to patch at the end.
    Stdout(StreamWriter<PipeOut>),
    File(FileStreamWriter),
    Bag(Box<BagWriter>),
}

/// An open output.
pub(crate) struct Output {
    /// `None` once finished or given up.
    sink: Option<Sink>,
    landing: Landing,
    /// A ROS 2 bag.
    bag: bool,
    /// An I/O error was returned with a note of what it leaves at `--out`.
    failed: bool,
}

impl Output {
    /// The MCAP file or stream file as the finished output has it.
    pub(crate) fn final_path(&self) -> std::path::PathBuf {
        self.landing.final_path()
    }

    /// An I/O error, with what it leaves at `--out` when that is not the stream's own aborted
    /// mark: a bag left unfinished, or an earlier output kept.
    fn noted(&mut self, e: Error) -> Error {
        if e.is_broken_pipe() || !(self.bag || self.landing.replaces()) {
            return e;
        }
        match e {
            Error::Io { context, source } => {
                self.failed = true;
                Error::Io {
                    context: format!("{context} ({})", self.landing.left(self.bag)),
                    source,
                }
            }
            e => e,
        }
    }

    /// From now on payloads go into the pipe by reference when the output is a pipe or FIFO
    /// ([`super::splice`]); returns how many more frames the caller must then write before it
    /// changes a payload buffer again, and it must never free one (0: written by copy, no
    /// such promise).
    pub(crate) fn splice_payloads(&mut self) -> usize {
        match self.sink.as_mut() {
            Some(Sink::Stdout(w)) => match w.get_mut().splice_payloads() {
                true => super::splice::RETAIN,
                false => 0,
            },
            _ => 0,
        }
    }

    /// Writes a frame.
    pub(crate) fn write(&mut self, f: OutFrame<'_>) -> Result<()> {
        let r = match (self.sink.as_mut(), f.pixels) {
            (Some(Sink::Stdout(w)), px) => w.write_payload_crc(f.meta, stream_bytes(&px), f.crc),
            (Some(Sink::File(w)), px) => w.write_payload_crc(f.meta, stream_bytes(&px), f.crc),
            (Some(Sink::Bag(w)), Pixels::Message(m, _)) => {
                w.write_frame_message(f.meta, m, f.truth)
            }
            (Some(Sink::Bag(w)), Pixels::Bytes(b)) => w.write_frame(f.meta, b, f.truth),
            (None, _) => Err(Error::Invalid("the output is closed".into())),
        };
        r.map_err(|e| self.noted(e))
    }

    /// Completes the output and puts it in place (replacing an earlier one).
    pub(crate) fn finish(mut self) -> Result<()> {
        let r = match self.sink.take() {
            Some(Sink::Stdout(w)) => w
                .finish()
                .and_then(|mut w| w.flush().map_err(|e| Error::io("flushing stdout", e))),
            Some(Sink::File(w)) => w.finish().map(|_| ()),
            Some(Sink::Bag(w)) => w.finish(),
            None => Err(Error::Invalid("the output is closed".into())),
        };
        match r {
            Ok(()) => self.landing.commit(),
            Err(e) => Err(self.noted(e)),
        }
    }

    /// Ends an output whose run failed or was stopped, so that nothing takes it for complete:
    /// a stream written in place is marked aborted ([`FileStreamWriter::abort`]); a bag written
    /// in place is left unfinished (no footer, no `metadata.yaml`), which is how rosbag2 and
    /// MCAP readers tell a cut-off bag; a replacement is removed and the earlier output kept.
    /// Says on stderr what is left, unless an error already did.
    pub(crate) fn abort(mut self, reason: &str) -> Result<()> {
        let bag = self.bag;
        let sink = self.sink.take();
        if self.landing.replaces() {
            drop(sink);
            if !self.failed {
                eprintln!(
                    "psns: {} (this run did not complete)",
                    self.landing.left(bag)
                );
            }
            self.landing.discard();
            return Ok(());
        }
        match sink {
            Some(Sink::Stdout(mut w)) => {
                w.abort(reason)?;
                w.finish()?
                    .flush()
                    .map_err(|e| Error::io("flushing stdout", e))
            }
            Some(Sink::File(w)) => w.abort(reason).map(|_| ()),
            Some(Sink::Bag(w)) => {
                drop(w);
                if !self.failed {
                    eprintln!("psns: {}", self.landing.left(true));
                }
                Ok(())
            }
            None => Ok(()),
        }
    }

    /// Gives the output up (its input turned out bad): removes what was written, so nothing
    /// is left of it; an earlier output is kept.
    pub(crate) fn abandon(mut self) {
        drop(self.sink.take());
        self.landing.discard();
    }
}

/// The stream payload of a frame's pixels.
fn stream_bytes<'a>(px: &'a Pixels<'_>) -> &'a [u8] {
    match px {
        Pixels::Bytes(b) => b,
        Pixels::Message(m, lead) => &m[*lead..],
    }
}
