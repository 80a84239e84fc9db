//! Rendering the frames a client asks for: one pipeline per sensor setting, the region cropped
//! from the full-sensor frame, the truth CSV.

use super::*;

/// What a pipeline is built for: the settings the sensor model bakes in.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct PipeKey {
    pub(super) bit_depth: u8,
    pub(super) exposure: Exposure,
    pub(super) gain_db: f64,
    pub(super) black_level_dn: f64,
}

impl PipeKey {
    pub(super) fn of(base: &psns::sensor::SensorConfig, s: &Settings) -> Self {
        PipeKey {
            bit_depth: s.pixel_format.adc_bits(),
            exposure: if s.exposure_auto {
                match base.exposure {
                    a @ Exposure::Auto { .. } => a,
                    Exposure::Fixed { .. } => Exposure::auto(),
                }
            } else {
                Exposure::Fixed { us: s.exposure_us }
            },
            gain_db: s.gain_db,
            black_level_dn: s.black_level,
        }
    }
}

/// Pipelines kept for recent settings (a client switching between two pixel formats does not
/// rebuild the camera every time).
pub(super) const PIPELINES: usize = 2;

pub(super) struct Renderer {
    pub(super) base: SceneConfig,
    pub(super) clock: SceneClock,
    pub(super) pipes: Vec<(PipeKey, RawPipeline)>,
    pub(super) codes: Vec<u16>,
    pub(super) spare: Receiver<Image>,
    pub(super) sensor_size: (usize, usize),
}

/// One frame rendered: the block, its chunk values and its record.
pub(super) struct RenderedFrame {
    pub(super) block: GigeBlock,
    pub(super) truth: ChunkValues,
    pub(super) record: FrameRecord,
}

impl Renderer {
    fn pipeline(&mut self, key: &PipeKey) -> Result<usize> {
        if let Some(i) = self.pipes.iter().position(|(k, _)| k == key) {
            return Ok(i);
        }
        let mut cfg = self.base.clone();
        let mut sensor = self
            .pipes
            .first()
            .map(|(_, p)| p.sensor_config().clone())
            .expect("the first pipeline is built at start");
        sensor.bit_depth = key.bit_depth;
        sensor.exposure = key.exposure;
        sensor.gain_db = key.gain_db;
        sensor.black_level_dn = key.black_level_dn;
        cfg.raw.sensor = Some(sensor);
        let pipe = RawPipeline::new(&cfg)?;
        if self.pipes.len() >= PIPELINES {
            // the oldest after the first goes (the first keeps the sensor as configured)
            self.pipes.remove(1.min(self.pipes.len() - 1));
        }
        self.pipes.push((key.clone(), pipe));
        Ok(self.pipes.len() - 1)
    }

    fn render(&mut self, order: &FrameOrder, pose: &Pose) -> Result<RenderedFrame> {
        let s = &order.settings;
        let key = PipeKey::of(self.pipes[0].1.sensor_config(), s);
        let i = self.pipeline(&key)?;
        let pipe = &self.pipes[i].1;
        let mut codes = std::mem::take(&mut self.codes);
        let mut bytes = Vec::new();
        if let Ok(img) = self.spare.try_recv() {
            match img {
                Image::Codes(c) if codes.is_empty() => codes = c,
                Image::Bytes(b) => bytes = b,
                Image::Codes(_) => {}
            }
        }
        let req = self.clock.request(order.frame_index, pose, &key.exposure)?;
        let FrameResult { frame, record, .. } = pipe.render(req.into_codes(codes, 0))?;
        let fmt = s.pixel_format.packing();
        let (sw, sh) = self.sensor_size;
        let full = s.width as usize == sw && s.height as usize == sh;
        let image = if full && packing::codes_are_payload(fmt) {
            Image::Codes(frame.codes.data)
        } else {
            let region;
            let src: &[u16] = if full {
                &frame.codes.data
            } else {
                region = crop(&frame.codes.data, sw, s);
                &region
            };
            packing::pack(src, frame.bit_depth, fmt, false, &mut bytes)?;
            self.codes = frame.codes.data;
            Image::Bytes(bytes)
        };
        let region = [s.offset_x, s.offset_y, s.width, s.height];
        let truth = ChunkValues::of_record(&record, order.timestamp, region, s.pixel_format.code());
        let mut tail = Vec::new();
        if s.chunk_mode {
            chunk::append(&mut tail, image.as_ref().len(), s.chunks(), &truth);
        }
        let leader = Leader {
            payload_type: s.payload_type(),
            timestamp: order.timestamp,
            pixel_format: s.pixel_format.code(),
            width: s.width,
            height: s.height,
            offset_x: s.offset_x,
            offset_y: s.offset_y,
        };
        Ok(RenderedFrame {
            block: Block::new(
                order.block_id,
                leader,
                image,
                tail,
                order.channel.packet_size,
            ),
            truth,
            record,
        })
    }
}

/// The codes of the settings' region of a full-sensor frame `sensor_w` wide.
pub(super) fn crop(codes: &[u16], sensor_w: usize, s: &Settings) -> Vec<u16> {
    let (x, y, w, h) = (
        s.offset_x as usize,
        s.offset_y as usize,
        s.width as usize,
        s.height as usize,
    );
    let mut out = Vec::with_capacity(w * h);
    for r in y..y + h {
        out.extend_from_slice(&codes[r * sensor_w + x..r * sensor_w + x + w]);
    }
    out
}

/// One row of `--truth-csv`: a frame sent as block `block_id`.
pub(super) struct TruthRow<'a> {
    block_id: u16,
    f: &'a RenderedFrame,
    format: &'static str,
}

/// The columns of `--truth-csv`, each its name and its value in a row.
type TruthColumn = (&'static str, fn(&TruthRow) -> String);
const TRUTH_COLUMNS: &[TruthColumn] = &[
    ("block_id", |r| r.block_id.to_string()),
    ("frame_index", |r| r.f.record.frame_index.to_string()),
    ("timestamp_ns", |r| r.f.truth.timestamp.to_string()),
    ("t_s", |r| r.f.record.t_s.to_string()),
    ("exposure_us", |r| r.f.record.exposure_us.to_string()),
    ("gain_db", |r| r.f.record.gain_db.to_string()),
    ("black_level_dn", |r| r.f.record.black_level_dn.to_string()),
    ("qw", |r| r.f.record.attitude_wxyz[0].to_string()),
    ("qx", |r| r.f.record.attitude_wxyz[1].to_string()),
    ("qy", |r| r.f.record.attitude_wxyz[2].to_string()),
    ("qz", |r| r.f.record.attitude_wxyz[3].to_string()),
    ("sun_azimuth_deg", |r| {
        r.f.record.sun_azimuth_deg.to_string()
    }),
    ("sun_elevation_deg", |r| {
        r.f.record.sun_elevation_deg().to_string()
    }),
    ("pixel_format", |r| r.format.to_string()),
    ("width", |r| r.f.truth.region[2].to_string()),
    ("height", |r| r.f.truth.region[3].to_string()),
    ("offset_x", |r| r.f.truth.region[0].to_string()),
    ("offset_y", |r| r.f.truth.region[1].to_string()),
];

/// The header line of `--truth-csv`.
pub(super) fn truth_header() -> String {
    let names: Vec<&str> = TRUTH_COLUMNS.iter().map(|c| c.0).collect();
    names.join(",")
}

impl TruthRow<'_> {
    fn line(&self) -> String {
        let values: Vec<String> = TRUTH_COLUMNS.iter().map(|c| (c.1)(self)).collect();
        values.join(",")
    }
}

pub(super) fn render_loop(
    sh: &Shared,
    r: &mut Renderer,
    mut poses: Poses,
    tx: SyncSender<Outgoing>,
    mut truth: Option<&mut std::io::BufWriter<std::fs::File>>,
) -> Result<()> {
    let mut next: Option<Pose> = None;
    let mut ended = false;
    while !stopping() {
        if next.is_none() && !ended {
            match poses.next() {
                Some(Ok(p)) => next = Some(p),
                Some(Err(e)) => {
                    eprintln!("psns gige: no more frames: {e}");
                    ended = true;
                }
                None => {
                    eprintln!("psns gige: the trajectory ended: no more frames");
                    ended = true;
                }
            }
        }
        let order = {
            let mut d = sh.device();
            let poll = if ended {
                Poll::Idle
            } else {
                d.poll_frame(sh.now_ns())
            };
            match poll {
                Poll::Frame(o) => o,
                Poll::At(t) => {
                    let wait = Duration::from_nanos(t.saturating_sub(sh.now_ns())).min(POLL);
                    let _ = sh.wake.wait_timeout(d, wait);
                    continue;
                }
                Poll::Idle => {
                    let _ = sh.wake.wait_timeout(d, POLL);
                    continue;
                }
            }
        };
        let pose = next.take().expect("a pose before a frame");
        let f = match r.render(&order, &pose) {
            Ok(f) => f,
            Err(e) => {
                eprintln!(
                    "psns gige: frame {} cannot be rendered: {e}; no more frames",
                    order.frame_index
                );
                ended = true;
                continue;
            }
        };
        sh.device().frame_rendered(f.truth.exposure_us);
        if let Some(w) = truth.as_mut() {
            let row = TruthRow {
                block_id: order.block_id,
                f: &f,
                format: order.settings.pixel_format.name(),
            };
            let written = writeln!(w, "{}", row.line()).and_then(|()| w.flush());
            if let Err(e) = written {
                return Err(Error::io("writing --truth-csv", e));
            }
        }
        let out = Outgoing {
            block: Arc::new(f.block),
            k: order.k,
            dest: order.channel.destination(),
            do_not_fragment: order.channel.do_not_fragment,
            packet_delay_ns: order.channel.packet_delay,
            throughput: order
                .settings
                .throughput_limit_on
                .then_some(order.settings.throughput_limit),
        };
        if tx.send(out).is_err() {
            break;
        }
    }
    Ok(())
}
