//! The stream channel's sending side: blocks cut into GVSP packets, gathered and sent with
//! sendmmsg, paced by the packet delay and the link throughput limit, dropped on purpose
//! (`--drop-packets`), and resent from the ring on request.

use super::*;

pub(super) fn resend(sh: &Shared, block_id: u64, first: u32, last: u32, out: &mut Vec<u8>) {
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

pub(super) fn set_dont_fragment(sock: &UdpSocket, on: bool) {
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
pub(super) struct Outgoing {
    pub(super) block: Arc<GigeBlock>,
    pub(super) k: u64,
    pub(super) dest: Option<SocketAddrV4>,
    pub(super) do_not_fragment: bool,
    pub(super) packet_delay_ns: u32,
    pub(super) throughput: Option<u64>,
}

/// Whether data packet `id` of the `k`-th block is dropped on its first transmission.
pub(super) fn dropped(seed: u64, k: u64, id: u32, p: f64) -> bool {
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
pub(super) const BATCH: usize = 64;

/// Packets gathered for one `sendmmsg`: each is its head (in `heads`) and two slices of its
/// block, so the payload is copied once, by the kernel.
pub(super) struct Gather {
    pub(super) heads: Vec<Vec<u8>>,
    pub(super) iov: Vec<libc::iovec>,
    pub(super) msgs: Vec<libc::mmsghdr>,
    pub(super) n: usize,
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

pub(super) fn send_loop(
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
