//! `psns convert`: an existing psns frame stream into a ROS 2 bag, the same bag `psns stream
//! --format rosbag2|mcap` writes for the same frames.
//!
//! Every frame must be intact: a damaged record, a truncated end, a second stream or the end
//! record of an aborted stream in the input stops the conversion with exit code 2 and removes
//! what was written (a bag never silently misses frames the stream had). With `--partial` the
//! intact frames are converted and each frame left out is named on stderr. Dropped frames (an
//! index gap the producer flagged) are no damage: the bag keeps the frames there are, with their
//! indexes as MCAP sequence numbers.

use super::bag::{BagKind, BagOptions, Compression};
use super::progress::{Progress, Unit};
use super::stream::output::{OutFrame, OutputSpec, Pixels};
use psns::error::Error;
use psns::ros2::ImageEncoding;
use psns::stream::{Event, StreamReader, FLAG_LAST};
use std::path::PathBuf;

/// Options of `psns convert`.
#[derive(clap::Args)]
pub struct ConvertArgs {
    /// The psns stream to convert (a file, or - for stdin).
    #[arg(value_name = "STREAM|-")]
    input: PathBuf,
    /// The bag: a new or empty directory (rosbag2) or a new file (mcap), or a bag psns wrote
    /// there before, replaced when this one is complete.
    #[arg(long, value_name = "PATH")]
    out: PathBuf,
    /// The bag's format: rosbag2 (a directory: metadata.yaml and one MCAP file) or mcap (one
    /// file).
    #[arg(long, value_enum)]
    format: Format,
    /// Chunk compression.
    #[arg(long, value_enum, default_value = "none")]
    compression: Compression,
    /// Convert the intact frames of a stream that did not end whole: aborted by its producer
    /// (a run with --frames stopped early, a failed run), cut short (a kill, a full disk) or
    /// with damaged records; each frame left out is named on stderr. Without it such a stream
    /// is refused (exit 2).
    #[arg(long)]
    partial: bool,
}

/// The bag formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Format {
    Rosbag2,
    Mcap,
}

/// Runs `psns convert`.
pub fn run(a: ConvertArgs) -> anyhow::Result<()> {
    let opts = BagOptions {
        kind: match a.format {
            Format::Rosbag2 => BagKind::Rosbag2,
            Format::Mcap => BagKind::Mcap,
        },
        compression: a.compression,
        truth_images: false,
    };
    let spec = OutputSpec::check(&a.out, Some(opts))?;
    let input = psns::io::open_input(&a.input)?;
    let mut rd = StreamReader::new(input)?;
    let h = rd.header().clone();
    let name = a.input.display().to_string();
    if h.aborted && !a.partial {
        return Err(Error::Invalid(format!(
            "{name}: its producer aborted it (psns verify tells why; --partial converts its \
             intact frames); nothing written"
        ))
        .into());
    }
    let mut out = spec.open(&h)?;
    let enc = ImageEncoding::of_pixel_format(h.pixel_format);
    let mut codes: Vec<u16> = Vec::new();
    let (mut n, mut last, mut left_out) = (0u64, false, false);
    let total = (h.frame_count > 0).then_some(h.frame_count);
    let mut progress = Progress::new("psns convert", Unit::Frames, total, false);
    let partial = a.partial;
    // what is not an intact frame: refused, or with --partial left out and named
    let mut skip = |what: String| -> Result<(), Error> {
        if partial {
            eprintln!("psns convert: left out: {what}");
            left_out = true;
            Ok(())
        } else {
            Err(Error::Invalid(format!(
                "{name}: {what}; nothing written (psns verify {name} tells more; --partial \
                 converts the intact frames)"
            )))
        }
    };
    let res = loop {
        let ev = match rd.next_event() {
            Ok(Some(ev)) => ev,
            Ok(None) => break Ok(()),
            Err(e) => break Err(e),
        };
        let r = match ev {
            Event::Frame(f) if f.payload_crc_ok => {
                // mono8: the payload itself; else the codes, unpacked, as little-endian u16
                let r = if enc == ImageEncoding::Mono8 {
                    out.write(frame(&f.meta, &f.payload))
                } else {
                    f.codes_into(&h, &mut codes)
                        .and_then(|_| out.write(frame(&f.meta, bytemuck::cast_slice(&codes))))
                };
                if r.is_ok() {
                    last = f.meta.flags & FLAG_LAST != 0;
                    n += 1;
                    progress.inc(1);
                }
                rd.recycle(f.payload);
                r
            }
            Event::Frame(f) => skip(format!(
                "frame {} is damaged (payload CRC) at byte {}",
                f.meta.index, f.offset
            )),
            Event::Gap { from, to } => {
                eprintln!(
                    "psns convert: frames {from}..{to} are not in the stream (dropped by its producer)"
                );
                Ok(())
            }
            Event::Corrupt { offset, index, .. } => skip(match index {
                Some(i) => format!("frame {i}: a damaged record at byte {offset}"),
                None => format!("a damaged record at byte {offset}"),
            }),
            Event::Truncated { offset, index, .. } => skip(match index {
                Some(i) => format!("frame {i}: the record at byte {offset} is cut short"),
                None => format!("the record at byte {offset} is cut short"),
            }),
            Event::Skipped { offset, bytes } if !partial => {
                skip(format!("{bytes} unreadable bytes at byte {offset}"))
            }
            Event::Skipped { .. } => Ok(()),
            Event::Restart(_) => {
                match skip("it holds more than one stream (another file header)".into()) {
                    // the frames of the first stream only
                    Ok(()) => break Ok(()),
                    Err(e) => Err(e),
                }
            }
            Event::Aborted { reason, .. } => skip(format!("its producer aborted it: {reason}")),
        };
        if let Err(e) = r {
            break Err(e);
        }
    };
    drop(progress);
    match res {
        Ok(()) => {
            let path = out.final_path();
            out.finish()?;
            if !last && h.frame_count != n && !left_out {
                eprintln!(
                    "psns convert: the stream is unfinished (no last frame flagged): the bag holds the {n} frames it had"
                );
            }
            eprintln!("converted {n} frames into {}", path.display());
            Ok(())
        }
        Err(e) if e.is_usage() => {
            out.abandon();
            Err(e.into())
        }
        Err(e) => {
            let _ = out.abort(&e.to_string());
            Err(e.into())
        }
    }
}

/// A stream frame for the bag.
fn frame<'a>(meta: &'a psns::stream::FrameMeta, image: &'a [u8]) -> OutFrame<'a> {
    OutFrame {
        meta,
        pixels: Pixels::Bytes(image),
        crc: None,
        truth: None,
    }
}
