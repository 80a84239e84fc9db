//! `psns gige`: psns as a GigE Vision camera. A GenICam client (Aravis, `camera_aravis`,
//! `aravissrc`) discovers it, configures it and receives frames rendered on the fly.
//!
//! The protocol and the device's behaviour are the library's ([`psns::gige`]); this file owns
//! the sockets, the threads and the clock:
//! - the control thread answers GVCP on `--address:--port` (and discovery broadcasts), checks the
//!   heartbeat, and serves PACKETRESEND from the ring of recent blocks;
//! - the render thread asks the device when a frame is due (frame rate, triggers, acquisition
//!   mode), takes the next pose and renders frame k − 1 for block k by [`RawPipeline`] with the
//!   client's settings, exactly as `psns stream` renders it;
//! - the sender thread cuts each block into packets of the negotiated size and sends them,
//!   paced by DeviceLinkThroughputLimit and the packet delay, dropping `--drop-packets` of the
//!   data packets on their first transmission.
//!
//! SIGINT or SIGTERM ends it with exit code 0.

use super::poses::{Poses, TrajectoryArgs};
use super::progress::{Progress, Unit};
use psns::config::SceneConfig;
use psns::error::{Error, Result};
use psns::gige::chunk::{self, ChunkValues};
use psns::gige::gvcp::{self, Command};
use psns::gige::gvsp::{self, Block, BlockRing, Leader};
use psns::gige::registers::{Action, Device, DeviceInfo, FrameOrder, Poll, Settings};
use psns::options::{finite, RawArgs, SceneArgs, WorldArgs};
use psns::pipeline::{FrameResult, RawPipeline, SceneClock};
use psns::record::FrameRecord;
use psns::sensor::{packing, Exposure};
use psns::trajectory::Pose;
use std::io::Write;
use std::net::{Ipv4Addr, SocketAddrV4, UdpSocket};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

mod render;
mod send;
use render::*;
use send::*;

/// Options of `psns gige`.
#[derive(clap::Args)]
#[command(
    mut_arg("bit_depth", |a| a.hide(true)),
    mut_arg("pixel_format", |a| a.hide(true))
)]
pub struct GigeArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    raw: RawArgs,
    #[command(flatten)]
    world: WorldArgs,
    /// Address to listen on (GVCP) and send the stream from. Default: loopback only.
    #[arg(long, default_value = "127.0.0.1", value_name = "IPV4")]
    address: Ipv4Addr,
    /// GVCP port (GigE Vision clients use 3956; 0: any free port, printed at start).
    #[arg(long, default_value_t = gvcp::GVCP_PORT, value_name = "PORT")]
    port: u16,
    #[command(flatten)]
    trajectory: TrajectoryArgs,
    /// Drop this fraction (0..1) of the stream's data packets on their first transmission,
    /// chosen from the camera seed, block and packet (resent packets are never dropped).
    #[arg(long, value_parser = finite, default_value_t = 0.0, value_name = "P")]
    drop_packets: f64,
    /// Write one CSV row per block: block id, frame index, device timestamp, exposure, gain,
    /// attitude, sun.
    #[arg(long, value_name = "FILE")]
    truth_csv: Option<PathBuf>,
    /// Serial number the device reports (at most 15 bytes; default: psns- and the address in
    /// hex).
    #[arg(long)]
    serial: Option<String>,
}

/// Set when the device stops (a signal, or a thread that ended).
static STOP: AtomicBool = AtomicBool::new(false);

/// How much lower the render workers' priority is than the control and stream threads'
/// (nice increment).
const RENDER_NICENESS: libc::c_int = 5;

/// Builds the render pool (rayon's global pool, one worker per CPU) with its workers at a lower
/// priority than the rest of the process: a device that renders with every core still answers
/// GVCP and sends its packets on time, and a client on the same machine keeps up. Frames do not
/// depend on it.
fn lower_render_priority() {
    let _ = rayon::ThreadPoolBuilder::new()
        .start_handler(|_| {
            // SAFETY: gettid has no preconditions; setpriority on this thread's own id raises its
            // nice value (always permitted) or fails harmlessly
            unsafe {
                let tid = libc::gettid();
                let now = libc::getpriority(libc::PRIO_PROCESS, tid as libc::id_t);
                libc::setpriority(libc::PRIO_PROCESS, tid as libc::id_t, now + RENDER_NICENESS);
            }
        })
        .build_global();
}

fn stopping() -> bool {
    STOP.load(Ordering::SeqCst) || super::signals::stop_signal().is_some()
}

/// Blocks kept for PACKETRESEND, bytes of payload (at least the newest block).
const RING_BYTES: usize = 96 << 20;
/// How long a thread waits before it looks at the stop flag again.
const POLL: Duration = Duration::from_millis(50);
/// Bytes a packet occupies on an Ethernet link beyond its IP datagram: header 14, FCS 4,
/// preamble 8, inter-frame gap 12.
const ETHERNET_FRAMING: u64 = 38;
/// Packets may leave this far ahead of the throughput limit's schedule (a burst of at most this
/// much link time).
const PACING_SLACK: Duration = Duration::from_micros(500);

/// A block's image bytes: packed bytes, or (little-endian Mono16) the codes themselves.
enum Image {
    Bytes(Vec<u8>),
    Codes(Vec<u16>),
}

impl AsRef<[u8]> for Image {
    fn as_ref(&self) -> &[u8] {
        match self {
            Image::Bytes(b) => b,
            Image::Codes(c) => bytemuck::cast_slice(c),
        }
    }
}

type GigeBlock = Block<Image>;

/// What the device, the threads and the control socket share.
struct Shared {
    device: Mutex<Device>,
    wake: Condvar,
    ring: Mutex<BlockRing<Image>>,
    /// The socket stream packets (and resends, test packets) leave from.
    stream: UdpSocket,
    t0: Instant,
    stats: Stats,
}

#[derive(Default)]
struct Stats {
    blocks: AtomicU64,
    packets: AtomicU64,
    dropped: AtomicU64,
    resent: AtomicU64,
    send_errors: AtomicU64,
}

impl Shared {
    fn now_ns(&self) -> u64 {
        self.t0.elapsed().as_nanos() as u64
    }

    fn device(&self) -> std::sync::MutexGuard<'_, Device> {
        self.device.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// Runs `psns gige`.
pub fn run(a: GigeArgs) -> anyhow::Result<()> {
    if let Some(o) = psns::options::first_given(&[
        ("bit-depth", a.raw.bit_depth.is_some()),
        ("pixel-format", a.raw.pixel_format.is_some()),
    ]) {
        return Err(Error::Invalid(format!(
            "--{o} is not an option of psns gige: the client picks PixelFormat, and the ADC depth \
             follows it (8 bits for the 8-bit formats, 12 otherwise)"
        ))
        .into());
    }
    psns::error::check_range("drop-packets", a.drop_packets, 0.0, 0.999)?;
    // before anything uses rayon's pool
    lower_render_priority();
    let mut cfg = a.scene.scene()?;
    a.raw.apply(&mut cfg)?;
    a.world.apply(&mut cfg)?;
    let (w, h) = (cfg.camera.intrinsics.width, cfg.camera.intrinsics.height);
    if w % 2 != 0 || h % 2 != 0 {
        return Err(Error::Invalid(format!(
            "psns gige needs an even sensor size (whole 2 x 2 polarizer cells): {w} x {h}"
        ))
        .into());
    }
    if let Some(s) = &a.serial {
        if s.is_empty() || s.len() > 15 || !s.is_ascii() {
            return Err(
                Error::Invalid(format!("serial '{s}' must be 1..15 ASCII characters")).into(),
            );
        }
    }
    // everything the frames need is validated before a socket is opened
    let start = SceneClock::start_time(&cfg, a.trajectory.start_time.as_deref())?;
    let traj = a.trajectory.open(cfg.camera.attitude)?;
    let clock = SceneClock::new(&cfg, start, traj.has_place)?;
    // the camera powers up in Mono8, with an 8-bit ADC
    if let Some(s) = cfg.raw.sensor.as_mut() {
        s.bit_depth = Settings::default().pixel_format.adc_bits();
    }
    let base = RawPipeline::new(&cfg)?;
    let sensor = base.sensor_config().clone();
    let defaults = Settings {
        width: w as u32,
        height: h as u32,
        exposure_us: match sensor.exposure {
            Exposure::Fixed { us } => us,
            Exposure::Auto { .. } => 1000.0,
        },
        exposure_auto: matches!(sensor.exposure, Exposure::Auto { .. }),
        gain_db: sensor.gain_db,
        black_level: sensor.black_level_dn,
        ..Settings::default()
    };
    let info = DeviceInfo {
        serial: a
            .serial
            .clone()
            .unwrap_or_else(|| format!("psns-{:08X}", u32::from(a.address))),
        mac: {
            let o = a.address.octets();
            [0x02, 0x50, 0x53, o[1], o[2], o[3]]
        },
        sensor_width: w as u32,
        sensor_height: h as u32,
        temperature_c: sensor.temperature_c,
        defaults,
        ..DeviceInfo::default()
    };
    // sockets
    let bind = |addr: SocketAddrV4| {
        UdpSocket::bind(addr).map_err(|e| Error::io(format!("binding {addr}"), e))
    };
    let control = bind(SocketAddrV4::new(a.address, a.port))?;
    let stream = bind(SocketAddrV4::new(a.address, 0))?;
    let port = control.local_addr().map(|s| s.port()).unwrap_or(a.port);
    let discovery = broadcast_socket(port);
    let mut truth = match &a.truth_csv {
        Some(p) => {
            let f = std::fs::File::create(p)
                .map_err(|e| Error::io(format!("creating {}", p.display()), e))?;
            let mut w = std::io::BufWriter::new(f);
            writeln!(w, "{}", truth_header())
                .and_then(|()| w.flush())
                .map_err(|e| Error::io(format!("writing {}", p.display()), e))?;
            Some(w)
        }
        None => None,
    };
    let mut device = Device::new(info, psns::gige::xml::genicam_xml());
    device.set_source_port(stream.local_addr().map(|s| s.port()).unwrap_or(0));
    let serial = device.info().serial.clone();
    let shared = Arc::new(Shared {
        device: Mutex::new(device),
        wake: Condvar::new(),
        ring: Mutex::new(BlockRing::new(RING_BYTES)),
        stream,
        t0: Instant::now(),
        stats: Stats::default(),
    });
    super::signals::catch(&[libc::SIGINT, libc::SIGTERM]);
    control
        .set_read_timeout(Some(POLL))
        .map_err(|e| Error::io("setting the control socket's timeout", e))?;
    eprintln!(
        "psns gige: listening on {}:{port} (GVCP), serial {serial}, sensor {w} x {h}; \
         SIGINT or SIGTERM stops",
        a.address
    );
    let (block_tx, block_rx) = sync_channel::<Outgoing>(1);
    let (spare_tx, spare_rx) = sync_channel::<Image>(4);
    let mut threads = Vec::new();
    {
        let sh = shared.clone();
        let control = control
            .try_clone()
            .map_err(|e| Error::io("cloning the control socket", e))?;
        threads.push(spawn("psns-gvcp", move || {
            control_loop(&sh, &control, a.address)
        }));
    }
    if let Some(d) = discovery {
        let sh = shared.clone();
        let reply = control
            .try_clone()
            .map_err(|e| Error::io("cloning the control socket", e))?;
        threads.push(spawn("psns-discovery", move || {
            discovery_loop(&sh, &d, &reply, a.address)
        }));
    }
    {
        let sh = shared.clone();
        let seed = cfg.raw.seed;
        let drop = a.drop_packets;
        threads.push(spawn("psns-gvsp", move || {
            send_loop(&sh, block_rx, spare_tx, seed, drop)
        }));
    }
    let render = {
        let sh = shared.clone();
        let mut r = Renderer {
            base: cfg,
            clock,
            pipes: vec![(PipeKey::of(&sensor, &defaults_of(&shared)), base)],
            codes: Vec::new(),
            spare: spare_rx,
            sensor_size: (w, h),
        };
        let poses = traj.poses;
        spawn("psns-render", move || {
            render_loop(&sh, &mut r, poses, block_tx, truth.as_mut())
        })
    };
    while !stopping() && !render.is_finished() && threads.iter().all(|t| !t.is_finished()) {
        std::thread::sleep(POLL);
    }
    STOP.store(true, Ordering::SeqCst);
    shared.wake.notify_all();
    let mut failure = None;
    let mut join = |t: std::thread::JoinHandle<Result<()>>| match t.join() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => {
            failure.get_or_insert(e);
        }
        Err(_) => {
            failure.get_or_insert(Error::io(
                "psns gige",
                std::io::Error::other("a thread panicked"),
            ));
        }
    };
    for t in threads {
        join(t);
    }
    // the render thread may be waiting for a trajectory line on stdin: it is not waited for
    if render.is_finished() {
        join(render);
    }
    let s = &shared.stats;
    eprintln!(
        "psns gige: stopped after {} blocks ({} packets, {} dropped by --drop-packets, {} resent, \
         {} send errors)",
        s.blocks.load(Ordering::Relaxed),
        s.packets.load(Ordering::Relaxed),
        s.dropped.load(Ordering::Relaxed),
        s.resent.load(Ordering::Relaxed),
        s.send_errors.load(Ordering::Relaxed),
    );
    match failure {
        Some(e) => Err(e.into()),
        None => Ok(()),
    }
}

fn defaults_of(sh: &Shared) -> Settings {
    sh.device().settings().clone()
}

fn spawn(
    name: &str,
    f: impl FnOnce() -> Result<()> + Send + 'static,
) -> std::thread::JoinHandle<Result<()>> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn(f)
        .expect("spawning a thread")
}

/// A socket on 255.255.255.255:`port` for discovery broadcasts (shared with other devices on
/// this host); `None` when it cannot be had (then only unicast discovery works).
fn broadcast_socket(port: u16) -> Option<UdpSocket> {
    if port == 0 {
        return None;
    }
    use std::os::fd::FromRawFd;
    // SAFETY: a new datagram socket whose descriptor is owned by the UdpSocket made from it (or
    // closed on failure); setsockopt reads one int; bind reads one sockaddr_in of the given size
    unsafe {
        let fd = libc::socket(libc::AF_INET, libc::SOCK_DGRAM | libc::SOCK_CLOEXEC, 0);
        if fd < 0 {
            return None;
        }
        let one: libc::c_int = 1;
        let len = std::mem::size_of::<libc::c_int>() as libc::socklen_t;
        libc::setsockopt(
            fd,
            libc::SOL_SOCKET,
            libc::SO_REUSEADDR,
            &one as *const _ as *const libc::c_void,
            len,
        );
        let mut sa: libc::sockaddr_in = std::mem::zeroed();
        sa.sin_family = libc::AF_INET as libc::sa_family_t;
        sa.sin_port = port.to_be();
        sa.sin_addr.s_addr = u32::from(Ipv4Addr::BROADCAST).to_be();
        let r = libc::bind(
            fd,
            &sa as *const libc::sockaddr_in as *const libc::sockaddr,
            std::mem::size_of::<libc::sockaddr_in>() as libc::socklen_t,
        );
        if r != 0 {
            libc::close(fd);
            return None;
        }
        let s = UdpSocket::from_raw_fd(fd);
        s.set_read_timeout(Some(POLL)).ok()?;
        Some(s)
    }
}

/// The device's address as `peer` reaches it: the bound address, or for 0.0.0.0 the local
/// address the kernel would use toward `peer`.
fn local_ip_for(bound: Ipv4Addr, peer: SocketAddrV4) -> Ipv4Addr {
    if !bound.is_unspecified() {
        return bound;
    }
    UdpSocket::bind((Ipv4Addr::UNSPECIFIED, 0))
        .and_then(|s| s.connect(peer).and_then(|()| s.local_addr()))
        .ok()
        .and_then(|a| match a {
            std::net::SocketAddr::V4(v) => Some(*v.ip()),
            _ => None,
        })
        .unwrap_or(Ipv4Addr::LOCALHOST)
}

/// Whether `ip` is an address of this host (a socket can be bound to it).
fn is_local(ip: Ipv4Addr) -> bool {
    ip.is_loopback() || UdpSocket::bind((ip, 0)).is_ok()
}

fn control_loop(sh: &Shared, sock: &UdpSocket, bound: Ipv4Addr) -> Result<()> {
    let mut buf = vec![0u8; 2048];
    let mut out = Vec::new();
    while !stopping() {
        let got = match sock.recv_from(&mut buf) {
            Ok((n, std::net::SocketAddr::V4(from))) => Some((n, from)),
            Ok(_) => None,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock
                        | std::io::ErrorKind::TimedOut
                        | std::io::ErrorKind::Interrupted
                        | std::io::ErrorKind::ConnectionRefused
                ) =>
            {
                None
            }
            Err(e) => return Err(Error::io("receiving GVCP", e)),
        };
        let now = sh.now_ns();
        let outcome = {
            let mut d = sh.device();
            if d.tick(now) {
                eprintln!("psns gige: heartbeat timeout: control released");
            }
            got.map(|(n, from)| d.handle(from, local_ip_for(bound, from), &buf[..n], now))
        };
        let Some(outcome) = outcome else { continue };
        let from = got.map(|g| g.1).expect("a datagram");
        if let Some(r) = &outcome.reply {
            let _ = sock.send_to(r, from);
        }
        for act in outcome.actions {
            match act {
                Action::Resend {
                    block_id,
                    first,
                    last,
                } => resend(sh, block_id, first, last, &mut out),
                Action::FireTestPacket {
                    dest,
                    packet_size,
                    do_not_fragment,
                } => {
                    set_dont_fragment(&sh.stream, do_not_fragment);
                    let n = packet_size as usize - gvsp::IP_UDP_LEN;
                    let _ = sh.stream.send_to(&vec![0u8; n], dest);
                }
            }
        }
        sh.wake.notify_all();
    }
    Ok(())
}

/// Answers discovery broadcasts from this host (a device on loopback does not answer the
/// network).
fn discovery_loop(sh: &Shared, sock: &UdpSocket, reply: &UdpSocket, bound: Ipv4Addr) -> Result<()> {
    let mut buf = vec![0u8; 2048];
    while !stopping() {
        let (n, from) = match sock.recv_from(&mut buf) {
            Ok((n, std::net::SocketAddr::V4(from))) => (n, from),
            _ => continue,
        };
        let is_discovery = matches!(
            gvcp::decode_command(&buf[..n]),
            Ok(gvcp::Request {
                command: Command::Discovery,
                ..
            })
        );
        if !is_discovery || (bound.is_loopback() && !is_local(*from.ip())) {
            continue;
        }
        let now = sh.now_ns();
        let ip = local_ip_for(bound, from);
        let out = sh.device().handle(from, ip, &buf[..n], now);
        if let Some(r) = out.reply {
            let _ = reply.send_to(&r, from);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drops_are_reproducible_and_near_the_fraction() {
        let n = (1..=200u64)
            .flat_map(|k| (1..=500u32).map(move |id| (k, id)))
            .filter(|&(k, id)| dropped(7, k, id, 0.02))
            .count();
        assert!((1700..2300).contains(&n), "{n} of 100000");
        assert_eq!(dropped(7, 3, 4, 0.5), dropped(7, 3, 4, 0.5));
        assert!(!dropped(7, 3, 4, 0.0));
        let a: Vec<bool> = (1..100).map(|id| dropped(1, 1, id, 0.5)).collect();
        let b: Vec<bool> = (1..100).map(|id| dropped(2, 1, id, 0.5)).collect();
        assert_ne!(a, b, "the seed changes the pattern");
    }

    #[test]
    fn crop_takes_the_region() {
        let codes: Vec<u16> = (0..8 * 6).collect();
        let s = Settings {
            width: 4,
            height: 2,
            offset_x: 2,
            offset_y: 4,
            ..Settings::default()
        };
        assert_eq!(crop(&codes, 8, &s), [34, 35, 36, 37, 42, 43, 44, 45]);
    }
}
