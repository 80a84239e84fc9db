//! GVCP, the GigE Vision control protocol (UDP port 3956): command and acknowledge packets.
//!
//! Every packet starts with an 8-byte big-endian header. A command: key `0x42`, flags, command
//! code, body length, request id. An acknowledge: status, acknowledge code (the command's + 1),
//! body length, the request id it answers.
//!
//! | command | code | body | acknowledge body |
//! |---|---|---|---|
//! | DISCOVERY | 0x0002 | none | 248 bytes of device information ([`DISCOVERY_ACK_LEN`]) |
//! | PACKETRESEND | 0x0040 | channel (u16), block id (u16), first and last packet id (u32, 24 bits used); with the extended-id flag: reserved u32, first, last (u32), block id (u64) | none: the stream channel sends the packets |
//! | READREG | 0x0080 | 1..135 addresses (u32) | one u32 value per address |
//! | WRITEREG | 0x0082 | 1..67 (address, value) pairs | reserved u16, index u16: registers written |
//! | READMEM | 0x0084 | address (u32), reserved u16, count u16 (multiple of 4, at most 536) | address, then `count` bytes |
//! | WRITEMEM | 0x0086 | address (u32), 4..536 bytes (multiple of 4) | reserved u16, index u16: bytes written |
//!
//! ```
//! use psns::gige::gvcp::{decode_command, Command, Request, FLAG_ACK_REQUIRED};
//! let r = Request { flags: FLAG_ACK_REQUIRED, req_id: 7, command: Command::ReadReg(vec![0x0A00]) };
//! let b = r.encode();
//! assert_eq!(b, [0x42, 0x01, 0x00, 0x80, 0x00, 0x04, 0x00, 0x07, 0x00, 0x00, 0x0A, 0x00]);
//! assert_eq!(decode_command(&b), Ok(r));
//! ```

/// The GVCP UDP port of every GigE Vision device.
pub const GVCP_PORT: u16 = 3956;
/// First byte of every command.
pub const KEY: u8 = 0x42;
/// Header length of commands and acknowledges.
pub const HEADER_LEN: usize = 8;
/// Command flag: the sender wants an acknowledge.
pub const FLAG_ACK_REQUIRED: u8 = 0x01;
/// PACKETRESEND flag: 64-bit block ids and 32-bit packet ids.
pub const FLAG_EXTENDED_IDS: u8 = 0x10;
/// Largest READMEM count and WRITEMEM data length.
pub const MEM_MAX: usize = 536;
/// Most addresses in one READREG (a 540-byte body).
pub const READREG_MAX: usize = 135;
/// Most pairs in one WRITEREG.
pub const WRITEREG_MAX: usize = 67;
/// Body length of a DISCOVERY acknowledge (bootstrap registers 0x0000..0x00F8).
pub const DISCOVERY_ACK_LEN: usize = 0xF8;

/// Command codes; the acknowledge of command `c` is `c + 1`.
pub mod code {
    /// DISCOVERY_CMD.
    pub const DISCOVERY: u16 = 0x0002;
    /// BYE_CMD (close the control session).
    pub const BYE: u16 = 0x0004;
    /// PACKETRESEND_CMD.
    pub const PACKETRESEND: u16 = 0x0040;
    /// READREG_CMD.
    pub const READREG: u16 = 0x0080;
    /// WRITEREG_CMD.
    pub const WRITEREG: u16 = 0x0082;
    /// READMEM_CMD.
    pub const READMEM: u16 = 0x0084;
    /// WRITEMEM_CMD.
    pub const WRITEMEM: u16 = 0x0086;
}

/// GVCP status codes (the acknowledge's first 16 bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u16)]
pub enum Status {
    /// Command executed.
    Success = 0x0000,
    /// Command not supported by the device.
    NotImplemented = 0x8001,
    /// A parameter (a value, a length, a count) is not valid.
    InvalidParameter = 0x8002,
    /// An address that does not exist.
    InvalidAddress = 0x8003,
    /// A write to a read-only address.
    WriteProtect = 0x8004,
    /// An address or length that is not a multiple of 4.
    BadAlignment = 0x8005,
    /// The sender does not hold the privilege this access needs.
    AccessDenied = 0x8006,
    /// The device cannot do it now (e.g. a transport setting while acquiring).
    Busy = 0x8007,
    /// A requested stream packet is no longer available.
    PacketUnavailable = 0x800C,
    /// The header of the command is not valid.
    InvalidHeader = 0x800E,
    /// A requested stream block was dropped from the device's memory.
    PacketRemovedFromMemory = 0x8012,
    /// Unspecified error.
    Error = 0x8FFF,
}

impl Status {
    /// The status with this code, if it is one of [`Status`]'s.
    pub fn from_code(c: u16) -> Option<Status> {
        use Status::*;
        [
            Success,
            NotImplemented,
            InvalidParameter,
            InvalidAddress,
            WriteProtect,
            BadAlignment,
            AccessDenied,
            Busy,
            PacketUnavailable,
            InvalidHeader,
            PacketRemovedFromMemory,
            Error,
        ]
        .into_iter()
        .find(|s| *s as u16 == c)
    }
}

/// A decoded command body.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Command {
    /// Who is there?
    Discovery,
    /// The controlling application says goodbye.
    Bye,
    /// Read 32-bit registers.
    ReadReg(Vec<u32>),
    /// Write 32-bit registers, in order.
    WriteReg(Vec<(u32, u32)>),
    /// Read `count` bytes of device memory at `address`.
    ReadMem {
        /// First byte.
        address: u32,
        /// Bytes to read.
        count: u16,
    },
    /// Write bytes of device memory at `address`.
    WriteMem {
        /// First byte.
        address: u32,
        /// The bytes.
        data: Vec<u8>,
    },
    /// Send stream packets `first..=last` of a block again.
    PacketResend {
        /// Stream channel index.
        channel: u16,
        /// Block id (16 bits unless extended ids).
        block_id: u64,
        /// First packet id.
        first: u32,
        /// Last packet id.
        last: u32,
        /// 64-bit block ids and 32-bit packet ids.
        extended: bool,
    },
}

impl Command {
    /// The command code.
    pub fn code(&self) -> u16 {
        match self {
            Command::Discovery => code::DISCOVERY,
            Command::Bye => code::BYE,
            Command::ReadReg(_) => code::READREG,
            Command::WriteReg(_) => code::WRITEREG,
            Command::ReadMem { .. } => code::READMEM,
            Command::WriteMem { .. } => code::WRITEMEM,
            Command::PacketResend { .. } => code::PACKETRESEND,
        }
    }
}

/// A decoded command packet.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Request {
    /// Header flags ([`FLAG_ACK_REQUIRED`], ...).
    pub flags: u8,
    /// Request id, echoed in the acknowledge.
    pub req_id: u16,
    /// The command.
    pub command: Command,
}

/// Why a datagram is not a command the device can execute.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DecodeError {
    /// Not a GVCP command (shorter than a header, or no 0x42 key): dropped, never answered.
    NotGvcp,
    /// A GVCP command answered with `status` and no data: an unknown command, a body length
    /// that disagrees with the datagram, a malformed body.
    Reject {
        /// The command code (the acknowledge is `command + 1`).
        command: u16,
        /// The request id to echo.
        req_id: u16,
        /// The status to answer.
        status: Status,
    },
}

fn be16(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}

fn be32(b: &[u8], at: usize) -> u32 {
    u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Decodes a command datagram. Never panics: anything that is not a well-formed command is a
/// [`DecodeError`].
pub fn decode_command(b: &[u8]) -> Result<Request, DecodeError> {
    if b.len() < HEADER_LEN || b[0] != KEY {
        return Err(DecodeError::NotGvcp);
    }
    let flags = b[1];
    let command = be16(b, 2);
    let length = be16(b, 4) as usize;
    let req_id = be16(b, 6);
    let reject = |status| DecodeError::Reject {
        command,
        req_id,
        status,
    };
    // the body length must match the datagram (trailing bytes beyond it are not allowed either)
    if b.len() != HEADER_LEN + length {
        return Err(reject(Status::InvalidHeader));
    }
    let body = &b[HEADER_LEN..];
    let cmd = match command {
        code::DISCOVERY => Command::Discovery,
        code::BYE => Command::Bye,
        code::READREG => {
            if length == 0 || !length.is_multiple_of(4) || length / 4 > READREG_MAX {
                return Err(reject(Status::InvalidParameter));
            }
            Command::ReadReg((0..length / 4).map(|i| be32(body, 4 * i)).collect())
        }
        code::WRITEREG => {
            if length == 0 || !length.is_multiple_of(8) || length / 8 > WRITEREG_MAX {
                return Err(reject(Status::InvalidParameter));
            }
            Command::WriteReg(
                (0..length / 8)
                    .map(|i| (be32(body, 8 * i), be32(body, 8 * i + 4)))
                    .collect(),
            )
        }
        code::READMEM => {
            if length != 8 {
                return Err(reject(Status::InvalidParameter));
            }
            Command::ReadMem {
                address: be32(body, 0),
                count: be16(body, 6),
            }
        }
        code::WRITEMEM => {
            if length < 8 || length - 4 > MEM_MAX {
                return Err(reject(Status::InvalidParameter));
            }
            Command::WriteMem {
                address: be32(body, 0),
                data: body[4..].to_vec(),
            }
        }
        code::PACKETRESEND => {
            let extended = flags & FLAG_EXTENDED_IDS != 0;
            if extended {
                if length != 20 {
                    return Err(reject(Status::InvalidParameter));
                }
                Command::PacketResend {
                    channel: be16(body, 0),
                    first: be32(body, 4),
                    last: be32(body, 8),
                    block_id: u64::from_be_bytes(body[12..20].try_into().expect("8 bytes")),
                    extended,
                }
            } else {
                if length != 12 {
                    return Err(reject(Status::InvalidParameter));
                }
                Command::PacketResend {
                    channel: be16(body, 0),
                    block_id: be16(body, 2) as u64,
                    first: be32(body, 4) & 0x00FF_FFFF,
                    last: be32(body, 8) & 0x00FF_FFFF,
                    extended,
                }
            }
        }
        _ => return Err(reject(Status::NotImplemented)),
    };
    Ok(Request {
        flags,
        req_id,
        command: cmd,
    })
}

impl Request {
    /// The datagram of this command (what a client sends).
    pub fn encode(&self) -> Vec<u8> {
        let mut body = Vec::new();
        match &self.command {
            Command::Discovery | Command::Bye => {}
            Command::ReadReg(a) => a.iter().for_each(|x| body.extend(x.to_be_bytes())),
            Command::WriteReg(p) => p.iter().for_each(|(a, v)| {
                body.extend(a.to_be_bytes());
                body.extend(v.to_be_bytes());
            }),
            Command::ReadMem { address, count } => {
                body.extend(address.to_be_bytes());
                body.extend([0, 0]);
                body.extend(count.to_be_bytes());
            }
            Command::WriteMem { address, data } => {
                body.extend(address.to_be_bytes());
                body.extend(data);
            }
            Command::PacketResend {
                channel,
                block_id,
                first,
                last,
                extended,
            } => {
                body.extend(channel.to_be_bytes());
                if *extended {
                    body.extend([0, 0]);
                    body.extend(first.to_be_bytes());
                    body.extend(last.to_be_bytes());
                    body.extend(block_id.to_be_bytes());
                } else {
                    body.extend((*block_id as u16).to_be_bytes());
                    body.extend(first.to_be_bytes());
                    body.extend(last.to_be_bytes());
                }
            }
        }
        let mut b = Vec::with_capacity(HEADER_LEN + body.len());
        b.push(KEY);
        b.push(self.flags);
        b.extend(self.command.code().to_be_bytes());
        b.extend((body.len() as u16).to_be_bytes());
        b.extend(self.req_id.to_be_bytes());
        b.extend(body);
        b
    }
}

/// An acknowledge packet.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Ack {
    /// Status code ([`Status`] as u16).
    pub status: u16,
    /// Acknowledge code (command + 1).
    pub answer: u16,
    /// The request id answered.
    pub ack_id: u16,
    /// The body.
    pub body: Vec<u8>,
}

impl Ack {
    /// An acknowledge of `command` (the command's code) with `status` and `body`.
    pub fn new(command: u16, req_id: u16, status: Status, body: Vec<u8>) -> Self {
        Ack {
            status: status as u16,
            answer: command.wrapping_add(1),
            ack_id: req_id,
            body,
        }
    }

    /// The datagram.
    pub fn encode(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(HEADER_LEN + self.body.len());
        b.extend(self.status.to_be_bytes());
        b.extend(self.answer.to_be_bytes());
        b.extend((self.body.len() as u16).to_be_bytes());
        b.extend(self.ack_id.to_be_bytes());
        b.extend(&self.body);
        b
    }

    /// Decodes an acknowledge datagram (what a client receives); `None` when it is shorter than
    /// its header says.
    pub fn decode(b: &[u8]) -> Option<Ack> {
        if b.len() < HEADER_LEN {
            return None;
        }
        let length = be16(b, 4) as usize;
        let body = b.get(HEADER_LEN..HEADER_LEN + length)?;
        Some(Ack {
            status: be16(b, 0),
            answer: be16(b, 2),
            ack_id: be16(b, 6),
            body: body.to_vec(),
        })
    }
}

/// The body of a WRITEREG or WRITEMEM acknowledge: `index` registers (or bytes) written.
pub fn index_body(index: u16) -> Vec<u8> {
    let mut b = vec![0, 0];
    b.extend(index.to_be_bytes());
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_codes_round_trip() {
        for c in 0..=0xFFFFu16 {
            if let Some(s) = Status::from_code(c) {
                assert_eq!(s as u16, c);
            }
        }
        assert_eq!(Status::from_code(0x8006), Some(Status::AccessDenied));
        assert_eq!(Status::from_code(0x1234), None);
    }

    #[test]
    fn malformed_commands_are_rejected_with_a_status() {
        // too short / wrong key: dropped
        assert_eq!(
            decode_command(&[0x42, 1, 0, 0x80]),
            Err(DecodeError::NotGvcp)
        );
        assert_eq!(
            decode_command(&[0x43, 1, 0, 0x80, 0, 0, 0, 1]),
            Err(DecodeError::NotGvcp)
        );
        // length disagrees with the datagram
        let r = decode_command(&[0x42, 1, 0, 0x80, 0, 8, 0, 9, 0, 0, 0, 0]);
        assert_eq!(
            r,
            Err(DecodeError::Reject {
                command: 0x80,
                req_id: 9,
                status: Status::InvalidHeader
            })
        );
        // unknown command
        let r = decode_command(&[0x42, 1, 0x12, 0x34, 0, 0, 0, 2]);
        assert_eq!(
            r,
            Err(DecodeError::Reject {
                command: 0x1234,
                req_id: 2,
                status: Status::NotImplemented
            })
        );
        // READREG with a partial address
        let r = decode_command(&[0x42, 1, 0, 0x80, 0, 2, 0, 3, 0, 0]);
        assert!(matches!(
            r,
            Err(DecodeError::Reject {
                status: Status::InvalidParameter,
                ..
            })
        ));
    }

    #[test]
    fn packet_resend_standard_ids_keep_24_bits() {
        let r = Request {
            flags: 0,
            req_id: 1,
            command: Command::PacketResend {
                channel: 0,
                block_id: 0xBEEF,
                first: 3,
                last: 0x00FF_FFFF,
                extended: false,
            },
        };
        assert_eq!(decode_command(&r.encode()), Ok(r));
    }

    #[test]
    fn ack_layout() {
        let a = Ack::new(code::READREG, 0x0102, Status::AccessDenied, vec![]);
        assert_eq!(a.encode(), [0x80, 0x06, 0x00, 0x81, 0, 0, 0x01, 0x02]);
        assert_eq!(Ack::decode(&a.encode()), Some(a));
        assert_eq!(Ack::decode(&[0, 0, 0, 0x81, 0, 4, 0, 1, 0]), None);
    }
}
