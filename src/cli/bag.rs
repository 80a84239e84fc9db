//! ROS 2 bags as an output of `psns stream`, `psns convert` and `psns recover`: a rosbag2
//! directory (`metadata.yaml` + one MCAP file) or a bare MCAP file, with profile `ros2`,
//! `ros2msg` schemas and `cdr` messages (`docs/ros2.md`). The messages come from the library
//! (`psns::ros2`); [`McapBag`] writes the MCAP file and `metadata.yaml` of any bag, and
//! [`BagWriter`] the psns topics into one. Where the files go (in place, or replacing an
//! earlier bag) is the output's choice (`src/cli/stream/place.rs`).
//!
//! Whole or clearly unfinished, by rosbag2's and MCAP's own rules: the MCAP file gets its
//! summary and footer only when the last frame is in; a bag directory gets its `metadata.yaml`
//! (written atomically) only after that file is complete and synced. A run that fails or is
//! killed leaves a directory without `metadata.yaml` and an MCAP file without a footer, which
//! every reader refuses or reports as unfinished (`psns recover` finishes it).

use clap::ValueEnum;
use psns::camera::Intrinsics;
use psns::error::{Error, Result};
use psns::ros2::metadata::{BagInfo, Topic, OFFERED_QOS_V8};
use psns::ros2::msg::{
    CameraInfo, Float64MultiArray, Header, Image, Message, PoseStamped, TfMessage, Vector3Stamped,
};
use psns::ros2::{self as ros, FrameId, ImageEncoding, Time};
use psns::stream::{FileHeader, FrameMeta};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// Output formats of `psns stream` and `psns convert`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OutFormat {
    /// The psns frame stream (docs/stream-format.md).
    Psns,
    /// A rosbag2 directory: metadata.yaml and one MCAP file.
    Rosbag2,
    /// A bare MCAP file (profile ros2), e.g. for Foxglove.
    Mcap,
}

/// Chunk compression of the MCAP file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Compression {
    /// Chunks stored as they are (the default: raw sensor noise hardly compresses, and this
    /// keeps up with the stream).
    None,
    /// Chunks compressed with zstd (level 1), on the bag writer's thread.
    Zstd,
}

/// Options of the bag formats, shared by `psns stream` and `psns convert`.
#[derive(clap::Args, Clone, Debug)]
pub struct BagArgs {
    /// Output format: psns (frame stream), rosbag2 (--out DIR: a new or empty directory) or
    /// mcap (--out FILE.mcap).
    #[arg(long, value_enum, default_value = "psns")]
    pub format: OutFormat,
    /// Chunk compression of a rosbag2 or mcap output [default: none].
    #[arg(long, value_enum)]
    pub compression: Option<Compression>,
}

/// Which bag, where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BagKind {
    /// A rosbag2 directory.
    Rosbag2,
    /// A bare MCAP file.
    Mcap,
}

/// A bag output, checked.
#[derive(Clone, Debug, PartialEq)]
pub struct BagOptions {
    /// Directory or bare file.
    pub kind: BagKind,
    /// Chunk compression.
    pub compression: Compression,
    /// Also `/psns/truth/dolp` and `/psns/truth/aolp`.
    pub truth_images: bool,
}

impl BagArgs {
    /// The bag options, `None` for the psns format; options that would do nothing are refused.
    pub fn options(&self, truth_images: bool) -> Result<Option<BagOptions>> {
        let kind = match self.format {
            OutFormat::Psns => {
                if self.compression.is_some() || truth_images {
                    let opt = if truth_images {
                        "--truth-images"
                    } else {
                        "--compression"
                    };
                    return Err(Error::Invalid(format!(
                        "{opt} applies to a ROS 2 bag: add --format rosbag2 or --format mcap"
                    )));
                }
                return Ok(None);
            }
            OutFormat::Rosbag2 => BagKind::Rosbag2,
            OutFormat::Mcap => BagKind::Mcap,
        };
        Ok(Some(BagOptions {
            kind,
            compression: self.compression.unwrap_or(Compression::None),
            truth_images,
        }))
    }
}

/// Bytes of a bag's raw image message in front of its pixels (the CDR prefix of
/// [`BagWriter::write_frame_message`]): the same for every frame of a bag.
pub fn image_prefix_len(encoding: ImageEncoding, width: usize, height: usize) -> Result<usize> {
    let size = |name: &str, v: usize| {
        u32::try_from(v).map_err(|_| Error::range(name, v as f64, "1..4294967295"))
    };
    let header = Header {
        stamp: Time::default(),
        frame_id: FrameId::CameraOptical,
    };
    let prefix = Image::cdr_prefix(
        header,
        size("width", width)?,
        size("height", height)?,
        encoding,
    )?;
    Ok(prefix.len())
}

/// What the bag describes: the image geometry, the lens and the run's own description.
#[derive(Clone, Debug)]
pub struct BagSource {
    /// Intrinsics of the frames (size, focal length, pixel pitch, principal point, projection).
    pub intrinsics: Intrinsics,
    /// Encoding of the raw image.
    pub encoding: ImageEncoding,
    /// `custom_data` of metadata.yaml and the MCAP metadata record `psns`.
    pub custom_data: Vec<(String, String)>,
}

impl BagSource {
    /// The source described by a stream file header: geometry and camera constants, the
    /// projection from its JSON (`optics.projection`, rectilinear when absent), the producer,
    /// preset, seed and JSON as custom data.
    pub fn of_header(h: &FileHeader, encoding: ImageEncoding) -> Result<Self> {
        let projection = serde_json::from_str::<serde_json::Value>(&h.json)
            .ok()
            .and_then(|v| v["optics"]["projection"].as_str().map(str::to_owned))
            .map(|p| p.parse())
            .transpose()?
            .unwrap_or_default();
        let intrinsics = Intrinsics {
            width: h.width as usize,
            height: h.height as usize,
            focal_length_mm: h.camera.focal_length_mm,
            pixel_pitch_um: h.camera.pixel_pitch_um,
            principal_point: Some([h.camera.principal_col, h.camera.principal_row]),
            projection,
            lens: None,
        };
        Ok(BagSource {
            intrinsics,
            encoding,
            custom_data: vec![
                ("psns.producer".into(), h.producer.clone()),
                ("psns.preset".into(), h.preset.clone()),
                ("psns.seed".into(), h.seed.to_string()),
                ("psns.config".into(), h.json.clone()),
            ],
        })
    }
}

/// The MCAP file of a bag, opened by the output (`src/cli/stream/place.rs`).
#[derive(Debug)]
pub struct BagFile {
    /// The file, open for writing at its start.
    pub file: File,
    /// Where it is.
    pub path: PathBuf,
    /// A rosbag2 bag: the directory where `metadata.yaml` goes.
    pub dir: Option<PathBuf>,
    /// The file's name in the finished bag (`relative_file_paths` of `metadata.yaml`).
    pub file_name: String,
}

/// MCAP chunk target size. A chunk is closed before the message that finds it over this size,
/// so a full-size raw image ends its chunk, and small frames share one.
const CHUNK_SIZE: u64 = 4 << 20;

fn mcap_err(context: String, e: mcap::McapError) -> Error {
    match e {
        mcap::McapError::Io(io) => Error::io(context, io),
        e => Error::io(context, std::io::Error::other(e.to_string())),
    }
}

fn writing(path: &Path) -> String {
    format!("writing {}", path.display())
}

/// Writes a small file atomically and durably: a temporary name beside it, synced, renamed.
fn write_synced(path: &Path, text: &str) -> Result<()> {
    let tmp = path.with_file_name(format!(
        ".{}.tmp-{}",
        path.file_name().unwrap_or_default().to_string_lossy(),
        std::process::id()
    ));
    let r = (|| {
        let mut f = File::create(&tmp)?;
        f.write_all(text.as_bytes())?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    r.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(writing(path), e)
    })
}

/// A topic of a bag: name, type, channel, messages written.
#[derive(Clone, Debug)]
struct BagTopic {
    name: String,
    msg_type: String,
    channel: u16,
    count: u64,
}

/// Writes the MCAP file of a bag, and `metadata.yaml` for a rosbag2 directory: topics (a
/// `ros2msg` schema and a `cdr` channel each), messages into chunks, and at the end the
/// `rosbag2` metadata record, summary and footer.
pub struct McapBag {
    mcap: Option<mcap::Writer<Sink>>,
    path: PathBuf,
    dir: Option<PathBuf>,
    file_name: String,
    custom_data: Vec<(String, String)>,
    /// In channel order.
    topics: Vec<BagTopic>,
    start_ns: Option<u64>,
    end_ns: u64,
    /// A write failed: the bag cannot be finished.
    failed: bool,
}

impl McapBag {
    /// Starts the MCAP file in `file`; `custom_data` goes into `metadata.yaml` and the
    /// `rosbag2` metadata record.
    pub fn create(
        file: BagFile,
        compression: Compression,
        custom_data: Vec<(String, String)>,
    ) -> Result<Self> {
        let BagFile {
            file,
            path,
            dir,
            file_name,
        } = file;
        let regular = file.metadata().map(|m| m.is_file()).unwrap_or(false);
        let w = BufWriter::with_capacity(1 << 20, file);
        let sink = if regular {
            Sink::File(w)
        } else {
            Sink::Stream(mcap::write::NoSeek::new(w))
        };
        let wopts = mcap::WriteOptions::new()
            .profile("ros2")
            .library(format!("psns {}", env!("CARGO_PKG_VERSION")))
            .chunk_size(Some(CHUNK_SIZE))
            .disable_seeking(!regular)
            .compression(match compression {
                Compression::None => None,
                Compression::Zstd => Some(mcap::Compression::Zstd),
            })
            .compression_level(1)
            // the chunk CRCs would read every frame twice more on the writer's thread
            .calculate_chunk_crcs(false)
            .calculate_data_section_crc(false);
        let mcap = wopts
            .create(sink)
            .map_err(|e| mcap_err(writing(&path), e))?;
        Ok(McapBag {
            mcap: Some(mcap),
            path,
            dir,
            file_name,
            custom_data,
            topics: Vec::new(),
            start_ns: None,
            end_ns: 0,
            failed: false,
        })
    }

    /// Adds a topic: its `ros2msg` schema and its `cdr` channel with `metadata` (rosbag2's
    /// `offered_qos_profiles`); returns the channel id.
    pub fn add_topic(
        &mut self,
        name: &str,
        msg_type: &str,
        schema: &[u8],
        metadata: &BTreeMap<String, String>,
    ) -> Result<u16> {
        let m = self.writer()?;
        let r = m
            .add_schema(msg_type, "ros2msg", schema)
            .and_then(|s| m.add_channel(s, name, "cdr", metadata));
        let channel = r.map_err(|e| self.io_error(e))?;
        self.topics.push(BagTopic {
            name: name.into(),
            msg_type: msg_type.into(),
            channel,
            count: 0,
        });
        Ok(channel)
    }

    /// A psns topic, offering rosbag2's QoS profile.
    fn add_psns_topic(&mut self, name: &str, msg_type: &str, schema: &str) -> Result<u16> {
        let meta = BTreeMap::from([(
            "offered_qos_profiles".to_string(),
            OFFERED_QOS_V8.to_string(),
        )]);
        self.add_topic(name, msg_type, schema.as_bytes(), &meta)
    }

    fn writer(&mut self) -> Result<&mut mcap::Writer<Sink>> {
        if self.failed {
            return Err(Error::Invalid("the bag could not be written".into()));
        }
        self.mcap
            .as_mut()
            .ok_or_else(|| Error::Invalid("the bag is closed".into()))
    }

    fn io_error(&mut self, e: mcap::McapError) -> Error {
        self.failed = true;
        mcap_err(writing(&self.path), e)
    }

    /// Writes one message on `channel` (log time `log_ns`, publish time `publish_ns`).
    pub fn put(
        &mut self,
        channel: u16,
        sequence: u32,
        log_ns: u64,
        publish_ns: u64,
        data: &[u8],
    ) -> Result<()> {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence,
            log_time: log_ns,
            publish_time: publish_ns,
        };
        let m = self.writer()?;
        if let Err(e) = m.write_to_known_channel(&header, data) {
            return Err(self.io_error(e));
        }
        if let Some(t) = self.topics.iter_mut().find(|t| t.channel == channel) {
            t.count += 1;
        }
        self.start_ns = Some(self.start_ns.map_or(log_ns, |s| s.min(log_ns)));
        self.end_ns = self.end_ns.max(log_ns);
        Ok(())
    }

    /// What metadata.yaml says.
    fn info(&self) -> BagInfo {
        BagInfo {
            file: self.file_name.clone(),
            start_ns: self.start_ns.unwrap_or(0),
            end_ns: self.end_ns,
            topics: self
                .topics
                .iter()
                .map(|t| Topic {
                    name: t.name.clone(),
                    msg_type: t.msg_type.clone(),
                    count: t.count,
                })
                .collect(),
            custom_data: self.custom_data.clone(),
            ros_distro: String::new(),
        }
    }

    /// Messages written per topic, in channel order.
    pub fn counts(&self) -> Vec<(String, u64)> {
        self.topics
            .iter()
            .map(|t| (t.name.clone(), t.count))
            .collect()
    }

    /// Finishes the bag: the `rosbag2` metadata record, the MCAP summary and footer, a sync,
    /// then (rosbag2) `metadata.yaml`. After a failed write nothing more is written.
    pub fn finish(mut self) -> Result<()> {
        if self.failed {
            return Err(Error::Invalid("the bag could not be written".into()));
        }
        let info = self.info();
        let meta = mcap::records::Metadata {
            name: "rosbag2".into(),
            metadata: BTreeMap::from([
                ("serialized_metadata".to_string(), info.serialized()),
                ("ROS_DISTRO".to_string(), String::new()),
            ]),
        };
        let mut m = self.mcap.take().expect("open until finish");
        if let Err(e) = m.write_metadata(&meta).and_then(|_| m.finish().map(|_| ())) {
            drop(m.into_inner());
            return Err(self.io_error(e));
        }
        let (w, stream) = match m.into_inner() {
            Sink::File(w) => (w, false),
            Sink::Stream(w) => (w.into_inner(), true),
        };
        let f = w
            .into_inner()
            .map_err(|e| Error::io(writing(&self.path), e.into_error()))?;
        // the data is on disk before metadata.yaml says the bag is whole
        if !stream {
            f.sync_all()
                .map_err(|e| Error::io(writing(&self.path), e))?;
        }
        if let Some(dir) = &self.dir {
            write_synced(&dir.join("metadata.yaml"), &info.yaml())?;
        }
        Ok(())
    }
}

impl Drop for McapBag {
    /// A bag dropped unfinished stays unfinished: no footer (the MCAP writer would add one).
    fn drop(&mut self) {
        if let Some(m) = self.mcap.take() {
            drop(m.into_inner());
        }
    }
}

/// The MCAP file: seekable (a regular file, chunk headers patched in place) or not (a device or
/// FIFO: chunks are assembled in memory).
enum Sink {
    File(BufWriter<File>),
    Stream(mcap::write::NoSeek<BufWriter<File>>),
}

impl Write for Sink {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        match self {
            Sink::File(w) => w.write(b),
            Sink::Stream(w) => w.write(b),
        }
    }
    fn write_all(&mut self, b: &[u8]) -> std::io::Result<()> {
        match self {
            Sink::File(w) => w.write_all(b),
            Sink::Stream(w) => w.write_all(b),
        }
    }
    fn flush(&mut self) -> std::io::Result<()> {
        match self {
            Sink::File(w) => w.flush(),
            Sink::Stream(w) => w.flush(),
        }
    }
}

impl Seek for Sink {
    fn seek(&mut self, p: SeekFrom) -> std::io::Result<u64> {
        match self {
            Sink::File(w) => w.seek(p),
            Sink::Stream(w) => w.seek(p),
        }
    }
}

/// Channel ids of the topics, in the order they are added.
struct Channels {
    image: u16,
    camera_info: u16,
    pose: u16,
    sun: u16,
    tf: u16,
    truth: Option<(u16, u16)>,
    /// Added with the first frame that has class fractions (a world around the camera).
    classes: Option<u16>,
}

/// Writes psns frames into a bag: per frame the raw image, camera info, pose, sun and the
/// camera's transform on `/tf` (and the truth images).
pub struct BagWriter {
    bag: McapBag,
    source: BagSource,
    camera_info: CameraInfo,
    channels: Channels,
    /// A reused buffer for the image message.
    buf: Vec<u8>,
}

impl BagWriter {
    /// Starts the bag in `file`; schemas and channels are written at once.
    pub fn create(opts: &BagOptions, file: BagFile, source: BagSource) -> Result<Self> {
        let mut bag = McapBag::create(file, opts.compression, source.custom_data.clone())?;
        let image = bag.add_psns_topic(ros::TOPIC_IMAGE, Image::TYPE, Image::SCHEMA)?;
        let info_ch =
            bag.add_psns_topic(ros::TOPIC_CAMERA_INFO, CameraInfo::TYPE, CameraInfo::SCHEMA)?;
        let pose = bag.add_psns_topic(ros::TOPIC_POSE, PoseStamped::TYPE, PoseStamped::SCHEMA)?;
        let sun =
            bag.add_psns_topic(ros::TOPIC_SUN, Vector3Stamped::TYPE, Vector3Stamped::SCHEMA)?;
        let tf = bag.add_psns_topic(ros::TOPIC_TF, TfMessage::TYPE, TfMessage::SCHEMA)?;
        let truth = if opts.truth_images {
            Some((
                bag.add_psns_topic(ros::TOPIC_TRUTH_DOLP, Image::TYPE, Image::SCHEMA)?,
                bag.add_psns_topic(ros::TOPIC_TRUTH_AOLP, Image::TYPE, Image::SCHEMA)?,
            ))
        } else {
            None
        };
        let header = Header {
            stamp: Time::default(),
            frame_id: FrameId::CameraOptical,
        };
        let camera_info = ros::camera_info(header, &source.intrinsics)?;
        Ok(BagWriter {
            bag,
            source,
            camera_info,
            channels: Channels {
                image,
                camera_info: info_ch,
                pose,
                sun,
                tf,
                truth,
                classes: None,
            },
            buf: Vec::new(),
        })
    }

    fn put(&mut self, channel: u16, sequence: u32, t: Time, data: &[u8]) -> Result<()> {
        self.bag
            .put(channel, sequence, t.unix_ns(), t.unix_ns(), data)
    }

    /// Writes one frame: the raw image (`image`: the pixel bytes of the bag's encoding), the
    /// camera info, the pose, the sun and the transform, and with `truth` the DoLP and AoLP images; every
    /// message stamped with the exposure start. A stamp a bag cannot hold is refused before
    /// anything of the frame is written.
    pub fn write_frame(
        &mut self,
        meta: &FrameMeta,
        image: &[u8],
        truth: Option<(&[f32], &[f32])>,
    ) -> Result<()> {
        let header = self.image_header(meta)?;
        let (w, h) = self.size();
        let buf = std::mem::take(&mut self.buf);
        let msg = Image::new(header, w, h, self.source.encoding, image)?.to_cdr_in(buf)?;
        let r = self.write_messages(meta, header, &msg, truth);
        self.buf = msg;
        r
    }

    /// [`Self::write_frame`] of an image message made in place: `message` holds room for the
    /// image's CDR prefix ([`image_prefix_len`]) and then the pixel bytes; the prefix is
    /// written into it and the whole is the message, so the pixels are not copied.
    pub fn write_frame_message(
        &mut self,
        meta: &FrameMeta,
        message: &mut [u8],
        truth: Option<(&[f32], &[f32])>,
    ) -> Result<()> {
        let header = self.image_header(meta)?;
        let (w, h) = self.size();
        let enc = self.source.encoding;
        let prefix = Image::cdr_prefix(header, w, h, enc)?;
        let need = prefix.len() as u64 + w as u64 * h as u64 * enc.bytes_per_pixel() as u64;
        if message.len() as u64 != need {
            return Err(Error::Invalid(format!(
                "a {w} x {h} {} image message needs {need} bytes, got {}",
                enc.as_str(),
                message.len()
            )));
        }
        message[..prefix.len()].copy_from_slice(&prefix);
        self.write_messages(meta, header, message, truth)
    }

    /// Image width and height.
    fn size(&self) -> (u32, u32) {
        (
            self.source.intrinsics.width as u32,
            self.source.intrinsics.height as u32,
        )
    }

    /// The image's header: the exposure start in the camera optical frame; refused when the
    /// bag is broken or the stamp does not fit.
    fn image_header(&self, meta: &FrameMeta) -> Result<Header> {
        if self.bag.failed {
            return Err(Error::Invalid("the bag could not be written".into()));
        }
        Ok(Header {
            stamp: Time::from_unix_ns(meta.exposure_start_ns)?,
            frame_id: FrameId::CameraOptical,
        })
    }

    /// The frame's messages, `image` the whole CDR image message.
    fn write_messages(
        &mut self,
        meta: &FrameMeta,
        header: Header,
        image: &[u8],
        truth: Option<(&[f32], &[f32])>,
    ) -> Result<()> {
        let stamp = header.stamp;
        let (w, h) = self.size();
        let pose = ros::pose(meta)?.to_cdr()?;
        let sun = ros::sun(meta)?.to_cdr()?;
        let tf = ros::transform(meta)?.to_cdr()?;
        self.camera_info.header = header;
        let info = self.camera_info.to_cdr()?;
        let seq = meta.index as u32;
        self.put(self.channels.image, seq, stamp, image)?;
        self.put(self.channels.camera_info, seq, stamp, &info)?;
        self.put(self.channels.pose, seq, stamp, &pose)?;
        self.put(self.channels.sun, seq, stamp, &sun)?;
        self.put(self.channels.tf, seq, stamp, &tf)?;
        if let Some(a) = ros::classes(meta) {
            let ch = match self.channels.classes {
                Some(ch) => ch,
                None => {
                    let (name, t) = (ros::TOPIC_TRUTH_CLASSES, Float64MultiArray::TYPE);
                    let ch = self
                        .bag
                        .add_psns_topic(name, t, Float64MultiArray::SCHEMA)?;
                    *self.channels.classes.insert(ch)
                }
            };
            self.put(ch, seq, stamp, &a.to_cdr()?)?;
        }
        if let (Some((cd, ca)), Some((dolp, aolp))) = (self.channels.truth, truth) {
            for (ch, px) in [(cd, dolp), (ca, aolp)] {
                let bytes: &[u8] = bytemuck::cast_slice(px);
                let m = Image::new(header, w, h, ImageEncoding::Float32, bytes)?.to_cdr()?;
                self.put(ch, seq, stamp, &m)?;
            }
        }
        Ok(())
    }

    /// Finishes the bag ([`McapBag::finish`]).
    pub fn finish(self) -> Result<()> {
        self.bag.finish()
    }
}
