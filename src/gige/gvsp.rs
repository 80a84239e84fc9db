//! GVSP, the GigE Vision stream protocol: one block (an image) as a leader, data packets and a
//! trailer, each a UDP datagram with an 8-byte big-endian header (standard ids).
//!
//! | bytes | header field |
//! |---|---|
//! | 0..2 | status (0 = success) |
//! | 2..4 | block id (16 bits, 1..65535: 0 is never used) |
//! | 4 | packet format (bits 0..3: 1 leader, 2 trailer, 3 payload; bit 7 extended ids, 0 here) |
//! | 5..8 | packet id (24 bits): 0 leader, 1..=n data, n + 1 trailer |
//!
//! Leader body (image payload types): reserved u16, payload type u16, timestamp u64, pixel format
//! u32, width u32, height u32, offset x u32, offset y u32, padding x u16, padding y u16 (36 bytes).
//! Trailer body: reserved u16, payload type u16, height u32 (8 bytes). Data packets carry bytes
//! `(id − 1)·d .. id·d` of the block's payload, `d = packet_size − 36` ([`data_per_packet`]):
//! the packet size (register SCPS) counts the IP and UDP headers (28 bytes) and this header.
//!
//! ```
//! use psns::gige::gvsp::{BlockLayout, decode, Content};
//! let layout = BlockLayout::new(100, 72); // 36 bytes of data per packet
//! assert_eq!(layout.data_packets(), 3);
//! assert_eq!(layout.trailer_id(), 4);
//! let mut out = Vec::new();
//! let payload: Vec<u8> = (0..100).collect();
//! layout.data_packet(7, 3, &[&payload], &mut out);
//! let p = decode(&out).unwrap();
//! assert_eq!((p.block_id, p.packet_id), (7, 3));
//! assert_eq!(p.content, Content::Payload(&payload[72..]));
//! ```

/// GVSP header length (standard ids).
pub const HEADER_LEN: usize = 8;
/// IPv4 and UDP headers, counted in the packet size.
pub const IP_UDP_LEN: usize = 28;
/// Packet size overhead of a data packet: IP, UDP and GVSP headers.
pub const PACKET_OVERHEAD: usize = IP_UDP_LEN + HEADER_LEN;
/// Payload type: an image.
pub const PAYLOAD_IMAGE: u16 = 0x0001;
/// Payload type: an image followed by chunk data (GigE Vision 2.x "image extended chunk").
pub const PAYLOAD_IMAGE_CHUNK: u16 = 0x4001;
/// Leader body length for image payloads.
pub const LEADER_LEN: usize = 36;
/// Trailer body length for image payloads.
pub const TRAILER_LEN: usize = 8;
/// Packet format: leader.
pub const FORMAT_LEADER: u8 = 1;
/// Packet format: trailer.
pub const FORMAT_TRAILER: u8 = 2;
/// Packet format: payload (generic data).
pub const FORMAT_PAYLOAD: u8 = 3;
/// Largest packet id with standard ids.
pub const PACKET_ID_MAX: u32 = 0x00FF_FFFF;

/// The image fields of a leader.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Leader {
    /// [`PAYLOAD_IMAGE`] or [`PAYLOAD_IMAGE_CHUNK`].
    pub payload_type: u16,
    /// Device timestamp in ticks.
    pub timestamp: u64,
    /// Pixel format code (PFNC or vendor).
    pub pixel_format: u32,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Offset x of the region, pixels.
    pub offset_x: u32,
    /// Offset y of the region, pixels.
    pub offset_y: u32,
}

/// The next block id after `id`: 16 bits that skip 0 (65535 is followed by 1).
pub fn next_block_id(id: u16) -> u16 {
    if id == u16::MAX {
        1
    } else {
        id + 1
    }
}

/// The 16-bit block id of the `k`-th block since the device started (k = 1, 2, ...): ids wrap
/// from 65535 to 1, never 0.
pub fn block_id_of(k: u64) -> u16 {
    ((k.max(1) - 1) % 65535 + 1) as u16
}

/// Bytes of payload per data packet for a packet size (register SCPS, IP and UDP headers
/// included); 0 when the packet size cannot carry data.
pub fn data_per_packet(packet_size: u32) -> usize {
    (packet_size as usize).saturating_sub(PACKET_OVERHEAD)
}

/// How a block of `payload_len` bytes is cut into packets of a packet size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockLayout {
    /// Payload bytes of the block (image and chunks).
    pub payload_len: usize,
    /// Payload bytes per data packet (at least 1).
    pub per_packet: usize,
}

impl BlockLayout {
    /// The layout of `payload_len` bytes in packets of `packet_size` (IP and UDP headers
    /// included; sizes too small for one byte of data are treated as one byte).
    pub fn new(payload_len: usize, packet_size: u32) -> Self {
        BlockLayout {
            payload_len,
            per_packet: data_per_packet(packet_size).max(1),
        }
    }

    /// Data packets (ids 1..=n).
    pub fn data_packets(&self) -> u32 {
        self.payload_len.div_ceil(self.per_packet) as u32
    }

    /// The trailer's packet id (n + 1).
    pub fn trailer_id(&self) -> u32 {
        self.data_packets() + 1
    }

    /// Whether the block fits the 24-bit packet ids.
    pub fn fits(&self) -> bool {
        self.trailer_id() <= PACKET_ID_MAX
    }

    /// Byte range of the payload in data packet `id` (1..=n); empty outside.
    pub fn range(&self, id: u32) -> std::ops::Range<usize> {
        if id == 0 || id > self.data_packets() {
            return 0..0;
        }
        let start = (id as usize - 1) * self.per_packet;
        start..(start + self.per_packet).min(self.payload_len)
    }

    /// Writes data packet `id` of a block whose payload is the concatenation of `parts` into
    /// `out` (cleared first).
    pub fn data_packet(&self, block_id: u16, id: u32, parts: &[&[u8]], out: &mut Vec<u8>) {
        out.clear();
        header(out, 0, block_id, FORMAT_PAYLOAD, id);
        let r = self.range(id);
        let mut at = 0usize;
        for p in parts {
            let (lo, hi) = (at, at + p.len());
            let (a, b) = (r.start.max(lo), r.end.min(hi));
            if a < b {
                out.extend_from_slice(&p[a - lo..b - lo]);
            }
            at = hi;
        }
    }
}

fn header(out: &mut Vec<u8>, status: u16, block_id: u16, format: u8, packet_id: u32) {
    out.extend(status.to_be_bytes());
    out.extend(block_id.to_be_bytes());
    out.push(format);
    out.extend(&packet_id.to_be_bytes()[1..]);
}

/// Writes the leader (packet id 0) of block `block_id` into `out` (cleared first).
pub fn leader_packet(block_id: u16, l: &Leader, out: &mut Vec<u8>) {
    out.clear();
    header(out, 0, block_id, FORMAT_LEADER, 0);
    out.extend([0, 0]);
    out.extend(l.payload_type.to_be_bytes());
    out.extend(l.timestamp.to_be_bytes());
    for v in [l.pixel_format, l.width, l.height, l.offset_x, l.offset_y] {
        out.extend(v.to_be_bytes());
    }
    out.extend([0, 0, 0, 0]);
}

/// Writes the trailer (packet id `packet_id`) of block `block_id` into `out` (cleared first).
pub fn trailer_packet(
    block_id: u16,
    packet_id: u32,
    payload_type: u16,
    height: u32,
    out: &mut Vec<u8>,
) {
    out.clear();
    header(out, 0, block_id, FORMAT_TRAILER, packet_id);
    out.extend([0, 0]);
    out.extend(payload_type.to_be_bytes());
    out.extend(height.to_be_bytes());
}

/// A packet with only a header and an error status: what the device sends for a packet a
/// PACKETRESEND asks for and it no longer has.
pub fn status_packet(status: u16, block_id: u16, packet_id: u32, out: &mut Vec<u8>) {
    out.clear();
    header(out, status, block_id, FORMAT_PAYLOAD, packet_id);
}

/// What a packet carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Content<'a> {
    /// A leader.
    Leader(Leader),
    /// Payload bytes.
    Payload(&'a [u8]),
    /// A trailer: payload type and height.
    Trailer {
        /// Payload type.
        payload_type: u16,
        /// Height of the image, rows.
        height: u32,
    },
}

/// A decoded packet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Packet<'a> {
    /// Status (0 = success).
    pub status: u16,
    /// Block id.
    pub block_id: u16,
    /// Packet id.
    pub packet_id: u32,
    /// The content.
    pub content: Content<'a>,
}

/// Why a datagram is not a GVSP packet this module reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GvspError {
    /// Shorter than its header or its leader/trailer body.
    Short,
    /// Extended ids or a packet format other than leader, trailer, payload.
    Unsupported,
}

/// Decodes a GVSP packet (what a receiver does). Never panics.
pub fn decode(b: &[u8]) -> Result<Packet<'_>, GvspError> {
    if b.len() < HEADER_LEN {
        return Err(GvspError::Short);
    }
    let be32 = |at: usize| u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
    let status = u16::from_be_bytes([b[0], b[1]]);
    let block_id = u16::from_be_bytes([b[2], b[3]]);
    let format = b[4];
    let packet_id = be32(4) & PACKET_ID_MAX;
    if format & 0x80 != 0 {
        return Err(GvspError::Unsupported);
    }
    let body = &b[HEADER_LEN..];
    let content = match format & 0x0F {
        FORMAT_LEADER => {
            if body.len() < LEADER_LEN {
                return Err(GvspError::Short);
            }
            let at = HEADER_LEN;
            Content::Leader(Leader {
                payload_type: u16::from_be_bytes([b[at + 2], b[at + 3]]),
                timestamp: u64::from_be_bytes(b[at + 4..at + 12].try_into().expect("8 bytes")),
                pixel_format: be32(at + 12),
                width: be32(at + 16),
                height: be32(at + 20),
                offset_x: be32(at + 24),
                offset_y: be32(at + 28),
            })
        }
        FORMAT_TRAILER => {
            if body.len() < TRAILER_LEN {
                return Err(GvspError::Short);
            }
            Content::Trailer {
                payload_type: u16::from_be_bytes([b[HEADER_LEN + 2], b[HEADER_LEN + 3]]),
                height: be32(HEADER_LEN + 4),
            }
        }
        FORMAT_PAYLOAD => Content::Payload(body),
        _ => return Err(GvspError::Unsupported),
    };
    Ok(Packet {
        status,
        block_id,
        packet_id,
        content,
    })
}

/// A block kept after it was sent, so that any of its packets can be sent again; `I` holds
/// the image bytes.
pub struct Block<I: AsRef<[u8]> = Vec<u8>> {
    /// Block id.
    pub block_id: u16,
    /// The leader's fields.
    pub leader: Leader,
    /// How the payload is cut into packets.
    pub layout: BlockLayout,
    /// The image bytes.
    pub image: I,
    /// What follows the image in the payload (chunks), possibly empty.
    pub tail: Vec<u8>,
}

impl<I: AsRef<[u8]>> Block<I> {
    /// A block of `image` then `tail`, cut for `packet_size`.
    pub fn new(block_id: u16, leader: Leader, image: I, tail: Vec<u8>, packet_size: u32) -> Self {
        let layout = BlockLayout::new(image.as_ref().len() + tail.len(), packet_size);
        Block {
            block_id,
            leader,
            layout,
            image,
            tail,
        }
    }

    /// Writes packet `id` (0 leader, 1..=n data, n + 1 trailer) into `out`; false for an id
    /// past the trailer.
    pub fn packet(&self, id: u32, out: &mut Vec<u8>) -> bool {
        match self.packet_parts(id, out) {
            Some([a, b]) => {
                out.extend_from_slice(a);
                out.extend_from_slice(b);
                true
            }
            None => false,
        }
    }

    /// Packet `id` in parts, for a sender that gathers them without copying the payload: its
    /// head written into `head` (the whole leader or trailer, or a data packet's 8-byte header)
    /// and the payload bytes that follow as two slices of the block (image, then chunks; either
    /// may be empty). `None` past the trailer.
    pub fn packet_parts(&self, id: u32, head: &mut Vec<u8>) -> Option<[&[u8]; 2]> {
        let trailer = self.layout.trailer_id();
        if id == 0 {
            leader_packet(self.block_id, &self.leader, head);
        } else if id < trailer {
            head.clear();
            header(head, 0, self.block_id, FORMAT_PAYLOAD, id);
            let image: &[u8] = self.image.as_ref();
            let r = self.layout.range(id);
            let n = image.len();
            let a = &image[r.start.min(n)..r.end.min(n)];
            let b = &self.tail[r.start.max(n) - n..r.end.max(n) - n];
            return Some([a, b]);
        } else if id == trailer {
            trailer_packet(
                self.block_id,
                id,
                self.leader.payload_type,
                self.leader.height,
                head,
            );
        } else {
            return None;
        }
        Some([&[], &[]])
    }

    /// Payload bytes held.
    pub fn bytes(&self) -> usize {
        self.layout.payload_len
    }
}

/// The most recent blocks, for PACKETRESEND: at most `max_bytes` of payload, but always the
/// newest block.
pub struct BlockRing<I: AsRef<[u8]> = Vec<u8>> {
    blocks: std::collections::VecDeque<std::sync::Arc<Block<I>>>,
    max_bytes: usize,
    bytes: usize,
}

impl<I: AsRef<[u8]>> BlockRing<I> {
    /// An empty ring holding at most `max_bytes` of payload (and always the newest block).
    pub fn new(max_bytes: usize) -> Self {
        BlockRing {
            blocks: Default::default(),
            max_bytes,
            bytes: 0,
        }
    }

    /// Adds the newest block; returns the blocks that no longer fit, oldest first.
    pub fn push(&mut self, b: std::sync::Arc<Block<I>>) -> Vec<std::sync::Arc<Block<I>>> {
        self.bytes += b.bytes();
        self.blocks.push_back(b);
        let mut out = Vec::new();
        while self.bytes > self.max_bytes && self.blocks.len() > 1 {
            let old = self.blocks.pop_front().expect("more than one block");
            self.bytes -= old.bytes();
            out.push(old);
        }
        out
    }

    /// The newest block with this id.
    pub fn get(&self, block_id: u16) -> Option<std::sync::Arc<Block<I>>> {
        self.blocks
            .iter()
            .rev()
            .find(|b| b.block_id == block_id)
            .cloned()
    }

    /// Blocks held.
    pub fn len(&self) -> usize {
        self.blocks.len()
    }

    /// Whether the ring is empty.
    pub fn is_empty(&self) -> bool {
        self.blocks.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_ids_skip_zero() {
        assert_eq!(next_block_id(1), 2);
        assert_eq!(next_block_id(65535), 1);
        assert_eq!(block_id_of(1), 1);
        assert_eq!(block_id_of(65535), 65535);
        assert_eq!(block_id_of(65536), 1);
        assert_eq!(block_id_of(65537), 2);
        let mut id = 0xFFF0u16;
        for k in 0xFFF0u64..0x1_0020 {
            assert_eq!(block_id_of(k), id);
            id = next_block_id(id);
        }
    }

    #[test]
    fn full_frame_layout() {
        // Mono8 2448 x 2048 at packet size 8192: 8156 bytes per packet
        let l = BlockLayout::new(2448 * 2048, 8192);
        assert_eq!(l.per_packet, 8156);
        assert_eq!(l.data_packets(), 615);
        assert_eq!(l.range(615), 614 * 8156..2448 * 2048);
        assert!(l.fits());
    }

    #[test]
    fn leader_and_trailer_bytes() {
        let mut out = Vec::new();
        let l = Leader {
            payload_type: PAYLOAD_IMAGE,
            timestamp: 0x0102030405060708,
            pixel_format: 0x01080001,
            width: 2448,
            height: 2048,
            offset_x: 2,
            offset_y: 4,
        };
        leader_packet(0x1234, &l, &mut out);
        assert_eq!(out.len(), HEADER_LEN + LEADER_LEN);
        assert_eq!(&out[..8], &[0, 0, 0x12, 0x34, 1, 0, 0, 0]);
        assert_eq!(decode(&out).unwrap().content, Content::Leader(l));
        trailer_packet(9, 0x010203, PAYLOAD_IMAGE_CHUNK, 2048, &mut out);
        assert_eq!(&out[..8], &[0, 0, 0, 9, 2, 1, 2, 3]);
        assert_eq!(
            decode(&out).unwrap().content,
            Content::Trailer {
                payload_type: PAYLOAD_IMAGE_CHUNK,
                height: 2048
            }
        );
    }

    #[test]
    fn ring_keeps_recent_blocks_within_its_bytes() {
        use std::sync::Arc;
        let mut ring = BlockRing::new(250);
        let block = |id: u16| {
            Arc::new(Block::new(
                id,
                Leader::default(),
                vec![id as u8; 100],
                vec![],
                1500,
            ))
        };
        assert!(ring.push(block(1)).is_empty());
        assert!(ring.push(block(2)).is_empty());
        let gone = ring.push(block(3));
        assert_eq!(gone.iter().map(|b| b.block_id).collect::<Vec<_>>(), [1]);
        assert!(ring.get(1).is_none());
        assert_eq!(ring.get(3).unwrap().block_id, 3);
        // a block larger than the ring is still kept alone
        let mut small = BlockRing::new(10);
        small.push(block(1));
        assert_eq!(small.push(block(2)).len(), 1);
        assert_eq!(small.len(), 1);
        let b = ring.get(2).unwrap();
        let mut out = Vec::new();
        assert!(b.packet(0, &mut out));
        assert!(b.packet(1, &mut out));
        assert_eq!(
            decode(&out).unwrap().content,
            Content::Payload(&[2u8; 100][..])
        );
        assert!(b.packet(2, &mut out));
        assert!(matches!(
            decode(&out).unwrap().content,
            Content::Trailer { .. }
        ));
        assert!(!b.packet(3, &mut out));
        // a block whose data packets straddle the image and the chunks
        let b = Block::new(5, Leader::default(), vec![1u8; 50], vec![2u8; 30], 36 + 16);
        let mut joined = Vec::new();
        for id in 1..=b.layout.data_packets() {
            assert!(b.packet(id, &mut out));
            b.layout
                .data_packet(5, id, &[&[1u8; 50], &[2u8; 30]], &mut joined);
            assert_eq!(out, joined, "packet {id}");
        }
    }

    #[test]
    fn data_packets_span_parts() {
        let a: Vec<u8> = (0..10).collect();
        let b: Vec<u8> = (10..25).collect();
        let l = BlockLayout::new(25, (PACKET_OVERHEAD + 4) as u32);
        let mut all = Vec::new();
        let mut out = Vec::new();
        for id in 1..=l.data_packets() {
            l.data_packet(1, id, &[&a, &b], &mut out);
            match decode(&out).unwrap().content {
                Content::Payload(p) => all.extend_from_slice(p),
                c => panic!("{c:?}"),
            }
        }
        assert_eq!(all, (0..25).collect::<Vec<u8>>());
    }
}
