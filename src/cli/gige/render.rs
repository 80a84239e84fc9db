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

/// One frame rendered: the block and its truth.
pub(super) struct RenderedFrame {
    pub(super) block: GigeBlock,
    pub(super) truth: ChunkValues,
    pub(super) t_s: f64,
    pub(super) black_level_dn: f64,
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
        let half_ns = match key.exposure {
            Exposure::Fixed { us } => seconds_to_ns(us * 0.5e-6)?,
            Exposure::Auto { .. } => 0,
        };
        let t_ns = self.clock.exposure_start_ns(pose)?;
        let sun = self.clock.sun_at(pose, t_ns.saturating_add(half_ns))?;
        let mut codes = std::mem::take(&mut self.codes);
        let mut bytes = Vec::new();
        if let Ok(img) = self.spare.try_recv() {
            match img {
                Image::Codes(c) if codes.is_empty() => codes = c,
                Image::Bytes(b) => bytes = b,
                Image::Codes(_) => {}
            }
        }
        let (frame, _) = pipe.frame_at(sun, &pose.attitude, pose.t_s, order.frame_index, codes)?;
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
        let m = pose.attitude.enu_to_camera(sun.azimuth_deg);
        let truth = ChunkValues {
            exposure_us: frame.exposure_us,
            gain_db: frame.gain_db,
            timestamp: order.timestamp,
            frame_index: order.frame_index,
            attitude_wxyz: camera_to_enu_quaternion(&m),
            sun_azimuth_deg: sun.azimuth_deg,
            sun_elevation_deg: sun.elevation_deg(),
            region: [s.offset_x, s.offset_y, s.width, s.height],
            pixel_format: s.pixel_format.code(),
        };
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
            t_s: pose.t_s,
            black_level_dn: frame.black_level_dn,
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

/// Columns of `--truth-csv`.
pub const TRUTH_HEADER: &str = "block_id,frame_index,timestamp_ns,t_s,exposure_us,gain_db,\
black_level_dn,qw,qx,qy,qz,sun_azimuth_deg,sun_elevation_deg,pixel_format,width,height,\
offset_x,offset_y";

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
            let t = &f.truth;
            let q = t.attitude_wxyz;
            let s = &order.settings;
            let row = writeln!(
                w,
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                order.block_id,
                order.frame_index,
                order.timestamp,
                f.t_s,
                t.exposure_us,
                t.gain_db,
                f.black_level_dn,
                q[0],
                q[1],
                q[2],
                q[3],
                t.sun_azimuth_deg,
                t.sun_elevation_deg,
                s.pixel_format.name(),
                s.width,
                s.height,
                s.offset_x,
                s.offset_y
            )
            .and_then(|()| w.flush());
            if let Err(e) = row {
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
