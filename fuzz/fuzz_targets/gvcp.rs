//! Fuzzes the GigE Vision device's control path: any datagram, from either of two senders, to
//! a device in any state must never panic; every acknowledge is well formed and echoes the
//! request id.
#![no_main]
use libfuzzer_sys::fuzz_target;
use psns::gige::gvcp::{decode_command, Ack};
use psns::gige::registers::{Device, DeviceInfo};
use std::net::{Ipv4Addr, SocketAddrV4};
use std::sync::OnceLock;

/// The XML, made once (making it for every input would be most of the run's time).
static XML: OnceLock<String> = OnceLock::new();

fuzz_target!(|data: &[u8]| {
    let _ = decode_command(data);
    let _ = Ack::decode(data);
    let _ = psns::gige::gvsp::decode(data);
    let _ = psns::gige::chunk::chunks(data);
    // the input as a sequence of datagrams: [len, sender, bytes...]*
    let xml = XML.get_or_init(psns::gige::xml::genicam_xml).clone();
    let mut dev = Device::new(DeviceInfo::default(), xml);
    let mut rest = data;
    let mut now = 0u64;
    while rest.len() >= 2 {
        let (n, who) = (rest[0] as usize, rest[1]);
        rest = &rest[2..];
        let d = &rest[..n.min(rest.len())];
        rest = &rest[d.len()..];
        now += 10_000_000 * (who as u64 & 0x0F);
        let from = SocketAddrV4::new(Ipv4Addr::LOCALHOST, 40000 + (who as u16 & 1));
        let out = dev.handle(from, Ipv4Addr::LOCALHOST, d, now);
        if let Some(r) = out.reply {
            let a = Ack::decode(&r).expect("a well-formed acknowledge");
            assert_eq!(a.ack_id, u16::from_be_bytes([d[6], d[7]]));
        }
        dev.tick(now);
        let _ = dev.poll_frame(now);
    }
});
