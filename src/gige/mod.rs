//! GigE Vision 2.x as a device: the protocol alone, with no sockets, threads or clocks
//! (`psns gige`, `src/cli/gige/`, owns those and the frames).
//!
//! - [`gvcp`]: control packets (discovery, READREG/WRITEREG, READMEM/WRITEMEM, PACKETRESEND)
//!   and acknowledges with their status codes;
//! - [`gvsp`]: stream packets (leader, data, trailer), block ids, the ring of recent blocks that
//!   PACKETRESEND serves;
//! - [`registers`]: the bootstrap and feature registers and the device's behaviour (privilege,
//!   heartbeat, acquisition, triggers) as a state machine driven by datagrams and the time;
//! - [`xml`]: the GenICam description served from device memory;
//! - [`chunk`]: the chunk data appended to images;
//! - [`pixel`]: the pixel formats, with LUCID's polarized names.
//!
//! Register map, features and limits: `docs/gige.md`.

pub mod chunk;
pub mod gvcp;
pub mod gvsp;
pub mod pixel;
pub mod registers;
pub mod xml;
