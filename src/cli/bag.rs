//! ROS 2 bags as an output of `psns stream` and `psns convert`: a rosbag2 directory
//! (`metadata.yaml` + one MCAP file) or a bare MCAP file, with profile `ros2`, `ros2msg` schemas
//! and `cdr` messages (`docs/ros2.md`). The messages come from the library (`psns::ros2`); this
//! file owns the files.
//!
//! Whole or clearly unfinished, by rosbag2's and MCAP's own rules: the MCAP file is written in
//! place and gets its summary and footer only when the last frame is in; a bag directory gets
//! its `metadata.yaml` (written atomically) only after that file is complete and synced. A run
//! that fails or is killed leaves a directory without `metadata.yaml` and an MCAP file without a
//! footer, which every reader refuses or reports as unfinished.

use clap::ValueEnum;
use psns::camera::Intrinsics;
use psns::error::{Error, Result};
use psns::ros2::metadata::{BagInfo, Topic, OFFERED_QOS_V8};
use psns::ros2::msg::{CameraInfo, Header, Image, Message, PoseStamped, Vector3Stamped};
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

/// Checks `--out` for a bag before anything is rendered: a rosbag2 directory must be new or
/// empty, a bare MCAP file must not be a directory; stdout cannot hold either.
pub fn check_out(kind: &BagKind, out: &Path) -> Result<()> {
    if out.as_os_str() == "-" {
        return Err(Error::Invalid(
            "a ROS 2 bag is written to a path, not stdout: give --out DIR (rosbag2) or --out \
             FILE.mcap (mcap)"
                .into(),
        ));
    }
    match kind {
        BagKind::Rosbag2 => {
            if let Ok(m) = std::fs::symlink_metadata(out) {
                if !m.is_dir() {
                    return Err(Error::Invalid(format!(
                        "--out {}: exists and is not a directory (a rosbag2 bag is a new or \
                         empty directory)",
                        out.display()
                    )));
                }
                let mut it = std::fs::read_dir(out)
                    .map_err(|e| Error::io(format!("reading {}", out.display()), e))?;
                if it.next().is_some() {
                    return Err(Error::Invalid(format!(
                        "--out {}: the directory is not empty (a rosbag2 bag is a new or empty \
                         directory)",
                        out.display()
                    )));
                }
            }
            bag_name(out).map(|_| ())
        }
        BagKind::Mcap => {
            if out.is_dir() {
                return Err(Error::Invalid(format!(
                    "--out {}: is a directory (--format mcap writes one file; --format rosbag2 \
                     writes a directory)",
                    out.display()
                )));
            }
            Ok(())
        }
    }
}

/// The bag's name: the directory's last component (rosbag2 names its file `<name>_0.mcap`).
fn bag_name(dir: &Path) -> Result<String> {
    let abs = std::path::absolute(dir).map_err(|e| Error::io("resolving --out", e))?;
    let name = abs
        .components()
        .filter_map(|c| match c {
            std::path::Component::Normal(s) => Some(s.to_string_lossy().into_owned()),
            _ => None,
        })
        .next_back()
        .filter(|n| dir.file_name().is_some() && !n.is_empty());
    name.ok_or_else(|| {
        Error::Invalid(format!(
            "--out {}: name the bag's directory (e.g. --out run1)",
            dir.display()
        ))
    })
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
    truth: Option<(u16, u16)>,
}

/// Writes frames into a bag.
pub struct BagWriter {
    mcap: Option<mcap::Writer<Sink>>,
    /// The bag directory (rosbag2), where metadata.yaml goes.
    dir: Option<PathBuf>,
    /// The directory was made by this run (so an abandoned bag removes it).
    made_dir: bool,
    path: PathBuf,
    file_name: String,
    source: BagSource,
    camera_info: CameraInfo,
    channels: Channels,
    /// (topic, type, channel, count) in channel order.
    topics: Vec<(&'static str, &'static str, u16, u64)>,
    start_ns: Option<u64>,
    end_ns: u64,
    /// A reused buffer for the image message.
    buf: Vec<u8>,
    /// A write failed: the bag cannot be finished.
    failed: bool,
}

/// MCAP chunk target size: one raw frame per chunk, the small messages with it.
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

impl BagWriter {
    /// Creates the bag at `out` (already [`check_out`]ed): the directory and its MCAP file, or
    /// the bare MCAP file; schemas and channels are written at once.
    pub fn create(opts: &BagOptions, out: &Path, source: BagSource) -> Result<Self> {
        check_out(&opts.kind, out)?;
        let mut made_dir = false;
        let (dir, path, file_name) = match opts.kind {
            BagKind::Rosbag2 => {
                let name = bag_name(out)?;
                made_dir = !out.exists();
                psns::io::create_dir(out)?;
                let file = format!("{name}_0.mcap");
                (Some(out.to_path_buf()), out.join(&file), file)
            }
            BagKind::Mcap => {
                let name = out
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                (None, out.to_path_buf(), name)
            }
        };
        let f = File::create(&path)
            .map_err(|e| Error::io(format!("creating {}", path.display()), e))?;
        let regular = f.metadata().map(|m| m.is_file()).unwrap_or(false);
        let w = BufWriter::with_capacity(1 << 20, f);
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
            .compression(match opts.compression {
                Compression::None => None,
                Compression::Zstd => Some(mcap::Compression::Zstd),
            })
            .compression_level(1)
            // the chunk CRCs would read every frame twice more on the writer's thread
            .calculate_chunk_crcs(false)
            .calculate_data_section_crc(false);
        let mut mcap = wopts
            .create(sink)
            .map_err(|e| mcap_err(writing(&path), e))?;
        let mut topics = Vec::new();
        let mut add = |mcap: &mut mcap::Writer<Sink>,
                       topic: &'static str,
                       ty: &'static str,
                       schema: &'static str|
         -> Result<u16> {
            let s = mcap
                .add_schema(ty, "ros2msg", schema.as_bytes())
                .map_err(|e| mcap_err(writing(&path), e))?;
            let meta = BTreeMap::from([(
                "offered_qos_profiles".to_string(),
                OFFERED_QOS_V8.to_string(),
            )]);
            let c = mcap
                .add_channel(s, topic, "cdr", &meta)
                .map_err(|e| mcap_err(writing(&path), e))?;
            topics.push((topic, ty, c, 0u64));
            Ok(c)
        };
        let image = add(&mut mcap, ros::TOPIC_IMAGE, Image::TYPE, Image::SCHEMA)?;
        let info_ch = add(
            &mut mcap,
            ros::TOPIC_CAMERA_INFO,
            CameraInfo::TYPE,
            CameraInfo::SCHEMA,
        )?;
        let pose = add(
            &mut mcap,
            ros::TOPIC_POSE,
            PoseStamped::TYPE,
            PoseStamped::SCHEMA,
        )?;
        let sun = add(
            &mut mcap,
            ros::TOPIC_SUN,
            Vector3Stamped::TYPE,
            Vector3Stamped::SCHEMA,
        )?;
        let truth = if opts.truth_images {
            Some((
                add(&mut mcap, ros::TOPIC_TRUTH_DOLP, Image::TYPE, Image::SCHEMA)?,
                add(&mut mcap, ros::TOPIC_TRUTH_AOLP, Image::TYPE, Image::SCHEMA)?,
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
            mcap: Some(mcap),
            dir,
            made_dir,
            path,
            file_name,
            source,
            camera_info,
            channels: Channels {
                image,
                camera_info: info_ch,
                pose,
                sun,
                truth,
            },
            topics,
            start_ns: None,
            end_ns: 0,
            buf: Vec::new(),
            failed: false,
        })
    }

    /// Where the MCAP file is.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// What an I/O failure leaves behind, for its message.
    fn unfinished(&self) -> String {
        match &self.dir {
            Some(d) => format!(
                "writing {} (the bag {} is left unfinished: no metadata.yaml)",
                self.path.display(),
                d.display()
            ),
            None => format!(
                "writing {} (left unfinished: no MCAP footer)",
                self.path.display()
            ),
        }
    }

    fn io_error(&mut self, e: mcap::McapError) -> Error {
        self.failed = true;
        mcap_err(self.unfinished(), e)
    }

    fn put(&mut self, channel: u16, sequence: u32, t: Time, data: &[u8]) -> Result<()> {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence,
            log_time: t.unix_ns(),
            publish_time: t.unix_ns(),
        };
        let Some(m) = self.mcap.as_mut() else {
            return Err(Error::Invalid("the bag is closed".into()));
        };
        if let Err(e) = m.write_to_known_channel(&header, data) {
            return Err(self.io_error(e));
        }
        if let Some(t) = self.topics.iter_mut().find(|t| t.2 == channel) {
            t.3 += 1;
        }
        Ok(())
    }

    /// Writes one frame: the raw image (`image`: the pixel bytes of the bag's encoding), the
    /// camera info, the pose and the sun, and with `truth` the DoLP and AoLP images; every
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
        if self.failed {
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
        self.camera_info.header = header;
        let info = self.camera_info.to_cdr()?;
        let seq = meta.index as u32;
        self.put(self.channels.image, seq, stamp, image)?;
        self.put(self.channels.camera_info, seq, stamp, &info)?;
        self.put(self.channels.pose, seq, stamp, &pose)?;
        self.put(self.channels.sun, seq, stamp, &sun)?;
        if let (Some((cd, ca)), Some((dolp, aolp))) = (self.channels.truth, truth) {
            for (ch, px) in [(cd, dolp), (ca, aolp)] {
                let bytes: &[u8] = bytemuck::cast_slice(px);
                let m = Image::new(header, w, h, ImageEncoding::Float32, bytes)?.to_cdr()?;
                self.put(ch, seq, stamp, &m)?;
            }
        }
        let t = stamp.unix_ns();
        self.start_ns = Some(self.start_ns.map_or(t, |s| s.min(t)));
        self.end_ns = self.end_ns.max(t);
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
                .map(|&(name, ty, _, count)| Topic {
                    name: name.into(),
                    msg_type: ty.into(),
                    count,
                })
                .collect(),
            custom_data: self.source.custom_data.clone(),
            ros_distro: String::new(),
        }
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
        let sink = m.into_inner();
        let (w, stream) = match sink {
            Sink::File(w) => (w, false),
            Sink::Stream(w) => (w.into_inner(), true),
        };
        let f = w
            .into_inner()
            .map_err(|e| Error::io(self.unfinished(), e.into_error()))?;
        // the data is on disk before metadata.yaml says the bag is whole
        if !stream {
            f.sync_all().map_err(|e| Error::io(self.unfinished(), e))?;
        }
        if let Some(dir) = &self.dir {
            write_synced(&dir.join("metadata.yaml"), &info.yaml()).map_err(|e| match e {
                Error::Io { context, source } => Error::Io {
                    context: format!("{context} (the bag {} is left unfinished)", dir.display()),
                    source,
                },
                e => e,
            })?;
        }
        Ok(())
    }

    /// Stops writing the bag of a run that failed or was stopped: no summary, footer or
    /// `metadata.yaml` are written, so it reads as unfinished; returns a note saying so.
    pub fn leave_unfinished(self) -> String {
        let note = match &self.dir {
            Some(d) => format!(
                "the bag {} is left unfinished: no metadata.yaml",
                d.display()
            ),
            None => format!("{} is left unfinished: no MCAP footer", self.path.display()),
        };
        drop(self);
        note
    }

    /// Gives the bag up (the input turned out bad): removes the MCAP file, and the directory if
    /// this run made it, so nothing is left of it.
    pub fn abandon(mut self) {
        if let Some(m) = self.mcap.take() {
            drop(m.into_inner());
        }
        let _ = std::fs::remove_file(&self.path);
        if let (Some(d), true) = (&self.dir, self.made_dir) {
            let _ = std::fs::remove_dir(d);
        }
    }
}

impl Drop for BagWriter {
    /// A bag dropped unfinished stays unfinished: no footer (the MCAP writer would add one).
    fn drop(&mut self) {
        if let Some(m) = self.mcap.take() {
            drop(m.into_inner());
        }
    }
}
