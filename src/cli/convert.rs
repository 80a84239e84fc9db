//! `psns convert`: an existing psns frame stream into a ROS 2 bag, the same bag `psns stream
//! --format rosbag2|mcap` writes for the same frames.
//!
//! Every frame must be intact: a damaged record, a truncated end or a second stream in the input
//! stops the conversion with exit code 2 and removes what was written (a bag never silently
//! misses frames the stream had). Dropped frames (an index gap the producer flagged) are no
//! damage: the bag keeps the frames there are, with their indexes as MCAP sequence numbers.

use super::bag::{BagKind, BagOptions, BagSource, BagWriter, Compression};
use super::progress::{Progress, Unit};
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
    /// The bag: a new or empty directory (rosbag2) or a file (mcap).
    #[arg(long, value_name = "PATH")]
    out: PathBuf,
    /// The bag's format: rosbag2 (a directory: metadata.yaml and one MCAP file) or mcap (one
    /// file).
    #[arg(long, value_enum)]
    format: Format,
    /// Chunk compression.
    #[arg(long, value_enum, default_value = "none")]
    compression: Compression,
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
    super::bag::check_out(&opts.kind, &a.out)?;
    let input = psns::io::open_input(&a.input)?;
    let mut rd = StreamReader::new(input)?;
    let h = rd.header().clone();
    if h.aborted {
        return Err(Error::Invalid(format!(
            "{}: its producer aborted it (psns verify tells why); nothing written",
            a.input.display()
        ))
        .into());
    }
    let enc = ImageEncoding::of_pixel_format(h.pixel_format);
    let src = BagSource::of_header(&h, enc)?;
    let mut bag = BagWriter::create(&opts, &a.out, src)?;
    let name = a.input.display().to_string();
    let mut codes: Vec<u16> = Vec::new();
    let (mut n, mut last) = (0u64, false);
    let total = (h.frame_count > 0).then_some(h.frame_count);
    let mut progress = Progress::new("psns convert", Unit::Frames, total, false);
    let bad = |what: String| {
        Error::Invalid(format!(
            "{name}: {what}; nothing written (psns verify {name} tells more)"
        ))
    };
    let res = loop {
        let ev = match rd.next_event() {
            Ok(Some(ev)) => ev,
            Ok(None) => break Ok(()),
            Err(e) => break Err(e),
        };
        let f = match ev {
            Event::Frame(f) if f.payload_crc_ok => f,
            Event::Frame(f) => {
                break Err(bad(format!(
                    "frame {} is damaged (payload CRC) at byte {}",
                    f.meta.index, f.offset
                )))
            }
            Event::Gap { from, to } => {
                eprintln!("psns convert: frames {from}..{to} are not in the stream (dropped by its producer)");
                continue;
            }
            Event::Corrupt { offset, .. } => {
                break Err(bad(format!("a damaged record at byte {offset}")))
            }
            Event::Truncated { offset, .. } => {
                break Err(bad(format!("the record at byte {offset} is cut short")))
            }
            Event::Skipped { offset, bytes } => {
                break Err(bad(format!("{bytes} unreadable bytes at byte {offset}")))
            }
            Event::Restart(_) => {
                break Err(bad(
                    "it holds more than one stream (another file header)".into()
                ))
            }
            Event::Aborted { reason, .. } => {
                break Err(bad(format!("its producer aborted it: {reason}")))
            }
        };
        // mono8: the payload itself; else the codes, unpacked, as little-endian u16
        let r = if enc == ImageEncoding::Mono8 {
            bag.write_frame(&f.meta, &f.payload, None)
        } else {
            f.codes_into(&h, &mut codes)
                .and_then(|_| bag.write_frame(&f.meta, bytemuck::cast_slice(&codes), None))
        };
        if let Err(e) = r {
            break Err(e);
        }
        last = f.meta.flags & FLAG_LAST != 0;
        n += 1;
        progress.inc(1);
        rd.recycle(f.payload);
    };
    drop(progress);
    match res {
        Ok(()) => {
            let path = bag.path().to_path_buf();
            bag.finish()?;
            if !last && h.frame_count != n {
                eprintln!(
                    "psns convert: the stream is unfinished (no last frame flagged): the bag holds the {n} frames it had"
                );
            }
            eprintln!("converted {n} frames into {}", path.display());
            Ok(())
        }
        Err(e) if e.is_usage() => {
            bag.abandon();
            Err(e.into())
        }
        Err(e) => Err(e.into()),
    }
}
