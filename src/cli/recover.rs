//! `psns recover`: a finished recording from what a `kill -9`, a full disk or a stopped run
//! left.
//!
//! - An MCAP file or rosbag2 directory without its summary, footer or `metadata.yaml` becomes a
//!   finished bag of every complete message: the records are read in file order up to where the
//!   file stops, every whole chunk is read, and the chunk the writer had open (its length never
//!   written) is read as far as its messages are whole (a zstd chunk is decoded as far as its
//!   data goes).
//! - A psns stream that is unfinished (count 0, no LAST flag, maybe a last record cut short) or
//!   aborted becomes a finished stream of its intact frames ([`psns::stream::Salvage`]): the same
//!   bytes `psns stream --frames N` writes for those N frames.
//!
//! The output is of the input's kind, written as `psns stream` writes its own (a new path, or an
//! earlier psns output of that kind, replaced when this one is complete), and appears whole or
//! not at all.

use super::bag::{BagKind, BagOptions, Compression};
use super::stream::output::{OutFrame, OutputSpec, Pixels, RawBag};
use mcap::records::{op, Record};
use psns::error::{Error, Result};
use psns::stream::{Salvage, StreamReader};
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

/// Options of `psns recover`.
#[derive(clap::Args)]
#[command(
    after_help = "Exit status: 0 recovered (what was left out is named on stderr); 1 an I/O \
failure; 2 bad input (not a psns stream, MCAP file or rosbag2 directory, nothing complete in it, \
a recording another psns run is still writing, or an --out that is not new or an earlier psns \
output of the same kind). The input is only read."
)]
pub struct RecoverArgs {
    /// The unfinished recording: a psns stream (or - for stdin), an MCAP file, or a rosbag2
    /// directory.
    #[arg(value_name = "PATH|-")]
    input: PathBuf,
    /// The finished recording, of the same kind: a new path, or an earlier psns output of that
    /// kind, replaced when this one is complete.
    #[arg(long, value_name = "PATH")]
    out: PathBuf,
}

/// MCAP's magic.
const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// What the input is.
enum Input {
    Stream,
    /// A bare MCAP file, or the MCAP file of a rosbag2 directory.
    Mcap(PathBuf, BagKind),
}

/// Runs `psns recover`.
pub fn run(a: RecoverArgs) -> anyhow::Result<()> {
    match input_kind(&a.input)? {
        Input::Stream => recover_stream(&a.input, &a.out)?,
        Input::Mcap(file, kind) => recover_bag(&file, kind, &a.out)?,
    }
    Ok(())
}

/// Tells a psns stream, an MCAP file and a rosbag2 directory apart; refuses a recording that
/// another psns run still writes (it holds the file's lock).
fn input_kind(input: &Path) -> Result<Input> {
    if input.as_os_str() == "-" {
        return Ok(Input::Stream);
    }
    let m = std::fs::metadata(input).map_err(|e| Error::input(input, e))?;
    let (file, kind) = if m.is_dir() {
        let mut mcaps: Vec<PathBuf> = std::fs::read_dir(input)
            .map_err(|e| Error::input(input, e))?
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "mcap") && p.is_file())
            .collect();
        if mcaps.len() != 1 {
            return Err(Error::Invalid(format!(
                "{}: a directory holding {} MCAP files; psns recover finishes a rosbag2 bag of \
                 one MCAP file",
                input.display(),
                mcaps.len()
            )));
        }
        (mcaps.remove(0), Some(BagKind::Rosbag2))
    } else {
        (input.to_path_buf(), None)
    };
    let f = File::open(&file).map_err(|e| Error::input(&file, e))?;
    if let Err(std::fs::TryLockError::WouldBlock) = f.try_lock() {
        return Err(Error::Invalid(format!(
            "{}: a psns run is still writing it; stop that run first (Ctrl-C finishes a run \
             without --frames cleanly)",
            input.display()
        )));
    }
    let mut magic = Vec::new();
    (&f).take(8)
        .read_to_end(&mut magic)
        .map_err(|e| Error::input(&file, e))?;
    if magic == MCAP_MAGIC {
        Ok(Input::Mcap(file, kind.unwrap_or(BagKind::Mcap)))
    } else if kind.is_none() && magic == psns::stream::FILE_MAGIC {
        Ok(Input::Stream)
    } else {
        Err(Error::Invalid(format!(
            "{}: not a psns stream, an MCAP file or a rosbag2 directory",
            input.display()
        )))
    }
}

/// A stream: its intact frames into a finished stream.
fn recover_stream(input: &Path, out: &Path) -> Result<()> {
    let spec = OutputSpec::check(out, None)?;
    let mut s = Salvage::new(StreamReader::new(psns::io::open_input(input)?)?);
    // nothing is written before the first intact frame is found
    let Some(mut f) = s.next_frame()? else {
        for n in s.notes() {
            eprintln!("psns recover: {n}");
        }
        return Err(Error::Invalid(format!(
            "{}: holds no intact frame; nothing written",
            input.display()
        )));
    };
    let mut o = spec.open(&s.header())?;
    let path = o.final_path();
    let res = loop {
        let frame = OutFrame {
            meta: &f.meta,
            pixels: Pixels::Bytes(&f.payload),
            crc: None,
            truth: None,
        };
        if let Err(e) = o.write(frame) {
            break Err(e);
        }
        s.recycle(f.payload);
        f = match s.next_frame() {
            Ok(Some(f)) => f,
            Ok(None) => break Ok(()),
            Err(e) => break Err(e),
        };
    };
    for n in s.notes() {
        eprintln!("psns recover: {n}");
    }
    if let Err(e) = res {
        o.abandon();
        return Err(e);
    }
    o.finish()?;
    eprintln!(
        "recovered {} intact frames into {}",
        s.frames(),
        path.display()
    );
    Ok(())
}

/// A bag: every complete message into a finished bag.
fn recover_bag(file: &Path, kind: BagKind, out: &Path) -> Result<()> {
    let opts = BagOptions {
        kind,
        compression: Compression::None,
        truth_images: false,
    };
    let spec = OutputSpec::check(out, Some(opts))?;
    let source = file
        .file_name()
        .unwrap_or_default()
        .to_string_lossy()
        .into_owned();
    let mut w = BagSalvage {
        spec: Some(spec),
        bag: None,
        source,
        schemas: HashMap::new(),
        channels: HashMap::new(),
        messages: 0,
    };
    let res = read_mcap(file, &mut w);
    let Some(bag) = w.bag.take() else {
        res?;
        return Err(Error::Invalid(format!(
            "{}: holds no complete channel or message; nothing written",
            file.display()
        )));
    };
    let finished = match res {
        Ok(finished) if w.messages > 0 => finished,
        Ok(_) => {
            bag.abandon();
            return Err(Error::Invalid(format!(
                "{}: holds no complete message; nothing written",
                file.display()
            )));
        }
        Err(e) => {
            bag.abandon();
            return Err(e);
        }
    };
    if finished {
        eprintln!("psns recover: the input has its footer: it was finished already");
    }
    let counts = bag.bag.counts();
    let path = bag.final_path();
    bag.finish()?;
    let per_topic: Vec<String> = counts.iter().map(|(t, n)| format!("{t} {n}")).collect();
    eprintln!(
        "recovered {} complete messages into {} ({})",
        w.messages,
        path.display(),
        per_topic.join(", ")
    );
    Ok(())
}

/// The output bag, opened at the first chunk or record (which gives the compression), and the
/// input's schemas and channels met so far.
struct BagSalvage {
    spec: Option<OutputSpec>,
    bag: Option<RawBag>,
    /// The input file's name, recorded in `custom_data`.
    source: String,
    /// Input schema id: name, encoding, text.
    schemas: HashMap<u16, (String, String, Vec<u8>)>,
    /// Input channel id: output channel id.
    channels: HashMap<u16, u16>,
    messages: u64,
}

impl BagSalvage {
    fn bag(&mut self, compression: Compression) -> Result<&mut RawBag> {
        if let Some(spec) = self.spec.take() {
            let custom = vec![("psns.recovered_from".to_string(), self.source.clone())];
            self.bag = Some(spec.open_bag(compression, custom)?);
        }
        self.bag
            .as_mut()
            .ok_or_else(|| Error::Invalid("the bag could not be opened".into()))
    }

    /// One record of the data section (or of a chunk).
    fn record(&mut self, r: Record<'_>, compression: Compression) -> Result<()> {
        match r {
            Record::Schema { header, data } => {
                self.schemas
                    .insert(header.id, (header.name, header.encoding, data.into_owned()));
            }
            Record::Channel(c) => {
                let Some((name, encoding, text)) = self.schemas.get(&c.schema_id).cloned() else {
                    return Err(Error::Format(format!(
                        "channel {} names schema {}, which the file does not hold",
                        c.topic, c.schema_id
                    )));
                };
                if encoding != "ros2msg" || c.message_encoding != "cdr" {
                    return Err(Error::Invalid(format!(
                        "channel {}: {encoding} schemas, {} messages; psns recover finishes ROS 2 \
                         bags (ros2msg schemas, cdr messages)",
                        c.topic, c.message_encoding
                    )));
                }
                let meta: BTreeMap<String, String> = c.metadata.clone();
                let id = self
                    .bag(compression)?
                    .bag
                    .add_topic(&c.topic, &name, &text, &meta)?;
                self.channels.insert(c.id, id);
            }
            Record::Message { header, data } => {
                let Some(&ch) = self.channels.get(&header.channel_id) else {
                    return Ok(()); // a message of no channel: nothing a reader could decode
                };
                self.bag(compression)?.bag.put(
                    ch,
                    header.sequence,
                    header.log_time,
                    header.publish_time,
                    &data,
                )?;
                self.messages += 1;
            }
            _ => {}
        }
        Ok(())
    }
}

/// The compression a chunk names.
fn compression(name: &str) -> Result<Compression> {
    match name {
        "" => Ok(Compression::None),
        "zstd" => Ok(Compression::Zstd),
        c => Err(Error::Invalid(format!(
            "chunks compressed with {c}; psns recover reads plain and zstd chunks"
        ))),
    }
}

fn mcap_format(at: u64, e: mcap::McapError) -> Error {
    Error::Format(format!("the MCAP record at byte {at}: {e}"))
}

/// Reads the records of an MCAP file in order into `w`, as far as they are whole. Returns true
/// when the data section ended (the file has its summary and footer).
fn read_mcap(file: &Path, w: &mut BagSalvage) -> Result<bool> {
    let f = File::open(file).map_err(|e| Error::input(file, e))?;
    let size = f.metadata().map_err(|e| Error::input(file, e))?.len();
    let mut r = BufReader::with_capacity(1 << 20, f);
    let io = |e: std::io::Error| Error::io(format!("reading {}", file.display()), e);
    let mut magic = [0u8; 8];
    r.read_exact(&mut magic).map_err(io)?;
    let mut at = 8u64;
    let mut body = Vec::new();
    let mut comp = Compression::None;
    loop {
        let mut head = [0u8; 9];
        if at + 9 > size {
            return Ok(false); // the end, or an opcode and length cut short
        }
        r.read_exact(&mut head).map_err(io)?;
        let opcode = head[0];
        let len = u64::from_le_bytes(head[1..].try_into().expect("8 bytes"));
        if opcode == op::DATA_END || opcode == op::FOOTER {
            return Ok(true);
        }
        let whole = len <= size - at - 9;
        let take = if whole { len } else { size - at - 9 };
        body.clear();
        (&mut r).take(take).read_to_end(&mut body).map_err(io)?;
        if !whole {
            // the record the writer was writing: a chunk gives the messages it has whole
            if opcode == op::CHUNK {
                open_chunk(&body, w, at)?;
            }
            return Ok(false);
        }
        match opcode {
            op::HEADER => {
                if let Ok(Record::Header(h)) = mcap::read::parse_record(opcode, &body) {
                    if h.profile != "ros2" {
                        return Err(Error::Invalid(format!(
                            "{}: an MCAP file of profile '{}'; psns recover finishes ROS 2 bags \
                             (profile ros2)",
                            file.display(),
                            h.profile
                        )));
                    }
                }
            }
            op::CHUNK => {
                let Record::Chunk { header, data } =
                    mcap::read::parse_record(opcode, &body).map_err(|e| mcap_format(at, e))?
                else {
                    return Err(Error::Format(format!("the chunk at byte {at}")));
                };
                comp = compression(&header.compression)?;
                let records =
                    mcap::read::ChunkReader::new(header, &data).map_err(|e| mcap_format(at, e))?;
                for rec in records {
                    w.record(rec.map_err(|e| mcap_format(at, e))?, comp)?;
                }
            }
            op::SCHEMA | op::CHANNEL | op::MESSAGE => {
                let rec =
                    mcap::read::parse_record(opcode, &body).map_err(|e| mcap_format(at, e))?;
                w.record(rec, comp)?;
            }
            _ => {}
        }
        at += 9 + len;
    }
}

/// The chunk an unfinished file ends in, its length never written: its records as far as they
/// are whole (a zstd chunk decoded as far as its data goes).
fn open_chunk(body: &[u8], w: &mut BagSalvage, at: u64) -> Result<()> {
    // message start and end time, uncompressed size, uncompressed CRC, compression, size
    let u32_at = |i: usize| {
        body.get(i..i + 4)
            .map(|b| u32::from_le_bytes(b.try_into().expect("4")))
    };
    let Some(n) = u32_at(28) else {
        return Ok(());
    };
    let name_end = 32 + n as usize;
    let Some(name) = body.get(32..name_end) else {
        return Ok(());
    };
    let comp = compression(&String::from_utf8_lossy(name))?;
    let Some(data) = body.get(name_end + 8..) else {
        return Ok(());
    };
    let decoded;
    let records: &[u8] = match comp {
        Compression::None => data,
        Compression::Zstd => {
            let mut out = Vec::new();
            if let Ok(mut d) = zstd::stream::read::Decoder::with_buffer(data) {
                // the decoder fails where the data stop; what it gave so far is whole
                let mut buf = vec![0u8; 1 << 16];
                while let Ok(k) = d.read(&mut buf) {
                    if k == 0 {
                        break;
                    }
                    out.extend_from_slice(&buf[..k]);
                }
            }
            decoded = out;
            &decoded
        }
    };
    let mut i = 0usize;
    while i + 9 <= records.len() {
        let opcode = records[i];
        let len = u64::from_le_bytes(records[i + 1..i + 9].try_into().expect("8 bytes"));
        let end = (i + 9).saturating_add(usize::try_from(len).unwrap_or(usize::MAX));
        let Some(rec) = records.get(i + 9..end) else {
            break;
        };
        let rec = mcap::read::parse_record(opcode, rec).map_err(|e| mcap_format(at, e))?;
        w.record(rec, comp)?;
        i = end;
    }
    Ok(())
}
