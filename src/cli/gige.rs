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

use super::poses::{open_trajectory, Poses};
use super::progress::{Progress, Unit};
use psns::camera::camera_to_enu_quaternion;
use psns::config::SceneConfig;
use psns::error::{Error, Result};
use psns::gige::chunk::{self, ChunkValues};
use psns::gige::gvcp::{self, Command};
use psns::gige::gvsp::{self, Block, BlockRing, Leader};
use psns::gige::registers::{Action, Device, DeviceInfo, FrameOrder, Poll, Settings};
use psns::options::{finite, RawArgs, SceneArgs};
use psns::pipeline::{seconds_to_ns, RawPipeline, SceneClock};
use psns::sensor::{packing, Exposure};
use psns::trajectory::Pose;
use std::io::Write;
use std::net::{Ipv4Addr, SocketAddrV4, UdpSocket};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

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
    /// Address to listen on (GVCP) and send the stream from. Default: loopback only.
    #[arg(long, default_value = "127.0.0.1", value_name = "IPV4")]
    address: Ipv4Addr,
    /// GVCP port (GigE Vision clients use 3956; 0: any free port, printed at start).
    #[arg(long, default_value_t = gvcp::GVCP_PORT, value_name = "PORT")]
    port: u16,
    /// Trajectory CSV (t_s, yaw_deg,pitch_deg,roll_deg or qw,qx,qy,qz [, lat_deg,lon_deg,height_m]); - for stdin. Default: built-in turning camera.
    #[arg(long, value_name = "PATH|-")]
    trajectory: Option<PathBuf>,
    /// Time zero of the trajectory, ISO 8601 UTC.
    #[arg(long, value_name = "TIME")]
    start_time: Option<String>,
    /// Built-in trajectory: yaw rate, degrees per second.
    #[arg(long, value_parser = finite, allow_negative_numbers = true, default_value_t = 10.0)]
    yaw_rate: f64,
    /// Built-in trajectory: frame interval, ms.
    #[arg(long, value_parser = finite, default_value_t = 50.0)]
    frame_interval_ms: f64,
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

/// Set by SIGINT and SIGTERM.
static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

fn install_signal_handlers() {
    // SAFETY: sigaction with a zeroed struct, an empty mask and a handler that only stores to an
    // atomic (async-signal-safe); the old action is not needed (null)
    unsafe {
        let mut sa: libc::sigaction = std::mem::zeroed();
        sa.sa_sigaction = on_signal as *const () as usize;
        libc::sigemptyset(&mut sa.sa_mask);
        libc::sigaction(libc::SIGINT, &sa, std::ptr::null_mut());
        libc::sigaction(libc::SIGTERM, &sa, std::ptr::null_mut());
    }
}

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
    STOP.load(Ordering::SeqCst)
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
    let start = SceneClock::start_time(&cfg, a.start_time.as_deref())?;
    let traj = open_trajectory(a.trajectory.as_deref(), a.yaw_rate, a.frame_interval_ms)?;
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
            writeln!(w, "{TRUTH_HEADER}")
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
    install_signal_handlers();
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

fn resend(sh: &Shared, block_id: u64, first: u32, last: u32, out: &mut Vec<u8>) {
    let Some(dest) = sh.device().channel().destination() else {
        return;
    };
    let block = u16::try_from(block_id)
        .ok()
        .and_then(|id| sh.ring.lock().unwrap_or_else(|e| e.into_inner()).get(id));
    let Some(block) = block else {
        // the block left the ring: say so once, so the client stops asking
        gvsp::status_packet(
            gvcp::Status::PacketUnavailable as u16,
            block_id as u16,
            first,
            out,
        );
        let _ = sh.stream.send_to(out, dest);
        return;
    };
    for id in first..=last.min(block.layout.trailer_id()) {
        if block.packet(id, out) {
            match sh.stream.send_to(out, dest) {
                Ok(_) => sh.stats.resent.fetch_add(1, Ordering::Relaxed),
                Err(_) => sh.stats.send_errors.fetch_add(1, Ordering::Relaxed),
            };
        }
    }
}

fn set_dont_fragment(sock: &UdpSocket, on: bool) {
    use std::os::fd::AsRawFd;
    let v: libc::c_int = if on {
        libc::IP_PMTUDISC_DO
    } else {
        libc::IP_PMTUDISC_DONT
    };
    // SAFETY: setsockopt on a socket this process holds, reading one int
    unsafe {
        libc::setsockopt(
            sock.as_raw_fd(),
            libc::IPPROTO_IP,
            libc::IP_MTU_DISCOVER,
            &v as *const _ as *const libc::c_void,
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        );
    }
}

/// A rendered block on its way to the sender.
struct Outgoing {
    block: Arc<GigeBlock>,
    k: u64,
    dest: Option<SocketAddrV4>,
    do_not_fragment: bool,
    packet_delay_ns: u32,
    throughput: Option<u64>,
}

/// Whether data packet `id` of the `k`-th block is dropped on its first transmission.
fn dropped(seed: u64, k: u64, id: u32, p: f64) -> bool {
    if p <= 0.0 {
        return false;
    }
    // SplitMix64 of (seed, block, packet): reproducible, independent of timing
    let mut z = seed ^ k.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ ((id as u64) << 40);
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 * (1.0 / (1u64 << 53) as f64) < p
}

/// Packets sent with one `sendmmsg` at most.
const BATCH: usize = 64;

/// Packets gathered for one `sendmmsg`: each is its head (in `heads`) and two slices of its
/// block, so the payload is copied once, by the kernel.
struct Gather {
    heads: Vec<Vec<u8>>,
    iov: Vec<libc::iovec>,
    msgs: Vec<libc::mmsghdr>,
    n: usize,
}

impl Gather {
    fn new() -> Self {
        Gather {
            heads: (0..BATCH).map(|_| Vec::with_capacity(64)).collect(),
            // SAFETY: iovec and mmsghdr are plain C structs; zero is a valid (empty) value
            iov: vec![unsafe { std::mem::zeroed() }; 3 * BATCH],
            // SAFETY: as above
            msgs: vec![unsafe { std::mem::zeroed() }; BATCH],
            n: 0,
        }
    }

    fn full(&self) -> bool {
        self.n == BATCH
    }

    /// Adds packet `id` of `block`, which must stay alive and unchanged until [`Self::flush`];
    /// the packet's length in bytes.
    fn push(&mut self, block: &GigeBlock, id: u32) -> usize {
        let i = self.n;
        let Some([a, b]) = block.packet_parts(id, &mut self.heads[i]) else {
            return 0;
        };
        let h = &self.heads[i];
        for (k, part) in [&h[..], a, b].into_iter().enumerate() {
            self.iov[3 * i + k] = libc::iovec {
                iov_base: part.as_ptr() as *mut libc::c_void,
                iov_len: part.len(),
            };
        }
        self.n += 1;
        h.len() + a.len() + b.len()
    }

    /// Sends the gathered packets to `dest`; (sent, failed).
    fn flush(&mut self, sock: &UdpSocket, dest: SocketAddrV4) -> (u64, u64) {
        use std::os::fd::AsRawFd;
        // SAFETY: a zeroed sockaddr_in is valid; the fields set make it `dest`
        let mut sa: libc::sockaddr_in = unsafe { std::mem::zeroed() };
        sa.sin_family = libc::AF_INET as libc::sa_family_t;
        sa.sin_port = dest.port().to_be();
        sa.sin_addr.s_addr = u32::from(*dest.ip()).to_be();
        for i in 0..self.n {
            let m = &mut self.msgs[i].msg_hdr;
            m.msg_name = &mut sa as *mut libc::sockaddr_in as *mut libc::c_void;
            m.msg_namelen = std::mem::size_of::<libc::sockaddr_in>() as libc::socklen_t;
            m.msg_iov = &mut self.iov[3 * i];
            m.msg_iovlen = 3;
            m.msg_control = std::ptr::null_mut();
            m.msg_controllen = 0;
            m.msg_flags = 0;
        }
        let (mut at, mut sent, mut failed) = (0usize, 0u64, 0u64);
        while at < self.n {
            // SAFETY: msgs[at..n] point at `sa` (alive for this call), at iovecs of this Gather
            // whose bases are the heads (not touched since push) and slices of blocks the
            // caller keeps alive until this returns
            let r = unsafe {
                libc::sendmmsg(
                    sock.as_raw_fd(),
                    self.msgs[at..].as_mut_ptr(),
                    (self.n - at) as libc::c_uint,
                    0,
                )
            };
            if r > 0 {
                at += r as usize;
                sent += r as u64;
            } else if std::io::Error::last_os_error().kind() == std::io::ErrorKind::Interrupted {
                continue;
            } else {
                // the first packet cannot be sent (e.g. a full device queue): skip it
                at += 1;
                failed += 1;
            }
        }
        self.n = 0;
        (sent, failed)
    }
}

fn send_loop(
    sh: &Shared,
    rx: Receiver<Outgoing>,
    spare: SyncSender<Image>,
    seed: u64,
    drop_p: f64,
) -> Result<()> {
    let mut gather = Gather::new();
    let mut progress = Progress::new("psns gige", Unit::Frames, None, false);
    // the throughput limit's schedule: when the link is free again
    let mut link_free = Instant::now();
    let count = |(sent, failed): (u64, u64)| {
        sh.stats.packets.fetch_add(sent, Ordering::Relaxed);
        sh.stats.send_errors.fetch_add(failed, Ordering::Relaxed);
    };
    while !stopping() {
        let o = match rx.recv_timeout(POLL) {
            Ok(o) => o,
            Err(RecvTimeoutError::Timeout) => continue,
            Err(RecvTimeoutError::Disconnected) => break,
        };
        // kept for resends before its first packet leaves; evicted blocks give their buffers back
        let evicted = sh
            .ring
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(o.block.clone());
        for b in evicted {
            if let Ok(b) = Arc::try_unwrap(b) {
                let _ = spare.try_send(b.image);
            }
        }
        if let Some(dest) = o.dest {
            set_dont_fragment(&sh.stream, o.do_not_fragment);
            let now = Instant::now();
            if link_free < now {
                link_free = now;
            }
            let paced = o.throughput.is_some() || o.packet_delay_ns > 0;
            let trailer = o.block.layout.trailer_id();
            for id in 0..=trailer {
                if stopping() {
                    break;
                }
                if paced {
                    // the packet leaves when the link is free; the delay between packets and the
                    // link's time for the packet move the schedule, so the average is exact
                    // even though the scheduler wakes the thread only every few tens of µs
                    let ahead = link_free.saturating_duration_since(Instant::now());
                    if ahead > PACING_SLACK {
                        count(gather.flush(&sh.stream, dest));
                        std::thread::sleep(ahead - PACING_SLACK);
                    }
                }
                let dropped_now = id != 0 && id != trailer && dropped(seed, o.k, id, drop_p);
                let len = if dropped_now {
                    sh.stats.dropped.fetch_add(1, Ordering::Relaxed);
                    o.block.layout.range(id).len() + gvsp::HEADER_LEN
                } else {
                    gather.push(&o.block, id)
                };
                if paced {
                    let mut ns = o.packet_delay_ns as u64;
                    if let Some(rate) = o.throughput {
                        let wire = (len + gvsp::IP_UDP_LEN) as u64 + ETHERNET_FRAMING;
                        ns += wire * 1_000_000_000 / rate;
                    }
                    link_free += Duration::from_nanos(ns);
                }
                if gather.full() {
                    count(gather.flush(&sh.stream, dest));
                }
            }
            // before the block can be dropped: the gathered packets point into it
            count(gather.flush(&sh.stream, dest));
        }
        drop(o);
        sh.stats.blocks.fetch_add(1, Ordering::Relaxed);
        progress.inc(1);
    }
    Ok(())
}

/// What a pipeline is built for: the settings the sensor model bakes in.
#[derive(Clone, Debug, PartialEq)]
struct PipeKey {
    bit_depth: u8,
    exposure: Exposure,
    gain_db: f64,
    black_level_dn: f64,
}

impl PipeKey {
    fn of(base: &psns::sensor::SensorConfig, s: &Settings) -> Self {
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
const PIPELINES: usize = 2;

struct Renderer {
    base: SceneConfig,
    clock: SceneClock,
    pipes: Vec<(PipeKey, RawPipeline)>,
    codes: Vec<u16>,
    spare: Receiver<Image>,
    sensor_size: (usize, usize),
}

/// One frame rendered: the block and its truth.
struct RenderedFrame {
    block: GigeBlock,
    truth: ChunkValues,
    t_s: f64,
    black_level_dn: f64,
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
        let (frame, _) = pipe.frame_at(sun, &pose.attitude, order.frame_index, codes)?;
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
fn crop(codes: &[u16], sensor_w: usize, s: &Settings) -> Vec<u16> {
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

fn render_loop(
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
